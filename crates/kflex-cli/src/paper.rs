//! The seed paper's figures, embedded from `assets/paper_tables.toml` so the
//! binary stands alone.

use anyhow::{Context, Result, anyhow};

const TABLES: &str = include_str!("../../../assets/paper_tables.toml");

/// A paper figure: mean and standard deviation over its repeats, deg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    pub mean: f64,
    pub std: f64,
}

/// Table IX, uncompensated ("none") row: RMSE and maximum hysteresis size at `sheath_deg`,
/// or `None` where the paper has no measurement at that bend.
pub fn table9_none(sheath_deg: f64) -> Result<Option<(Figure, Figure)>> {
    let root: toml::Table = TABLES
        .parse()
        .context("parsing the embedded paper tables")?;
    let t9 = root
        .get("table9_compensation_sheath")
        .and_then(|v| v.as_table())
        .ok_or_else(|| anyhow!("paper tables lack table9_compensation_sheath"))?;
    let sheaths =
        numbers(t9.get("sheath_deg")).ok_or_else(|| anyhow!("table 9 lacks sheath_deg"))?;
    let Some(i) = sheaths.iter().position(|s| (s - sheath_deg).abs() < 1e-9) else {
        return Ok(None);
    };
    let pair = |key: &str| -> Result<Figure> {
        let rows = t9
            .get(key)
            .and_then(|v| v.as_array())
            .ok_or_else(|| anyhow!("table 9 lacks {key}"))?;
        let row =
            numbers(rows.get(i)).ok_or_else(|| anyhow!("table 9 {key}[{i}] is not [mean, std]"))?;
        match row.as_slice() {
            [mean, std] => Ok(Figure {
                mean: *mean,
                std: *std,
            }),
            _ => Err(anyhow!("table 9 {key}[{i}] is not [mean, std]")),
        }
    };
    Ok(Some((pair("rmse_none")?, pair("max_hysteresis_none")?)))
}

fn numbers(v: Option<&toml::Value>) -> Option<Vec<f64>> {
    v?.as_array()?
        .iter()
        .map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_table_ix_none_row() {
        let (rmse, width) = table9_none(270.0).unwrap().unwrap();
        assert_eq!((rmse.mean, rmse.std), (21.9, 1.2));
        assert_eq!((width.mean, width.std), (18.4, 1.5));
        assert!(table9_none(45.0).unwrap().is_none());
    }
}
