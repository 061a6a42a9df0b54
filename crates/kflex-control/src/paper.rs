//! The seed paper's figures (Baek et al., RA-L 2020, Tables V–X), embedded
//! from `assets/paper_tables.toml` so a program stands alone (cargo feature
//! `paper`).

use crate::error::{ControlError, Result};

/// An error of the embedded tables (a test reads every one of them).
fn bad(what: String) -> ControlError {
    ControlError::Unavailable {
        what: format!("the paper's tables (assets/paper_tables.toml): {what}"),
    }
}

const TABLES: &str = include_str!("../../../assets/paper_tables.toml");

/// A paper figure: mean and standard deviation over its repeats, deg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperFigure {
    /// Mean, deg.
    pub mean: f64,
    /// Standard deviation, deg.
    pub std: f64,
}

/// The paper's figures for a case of its Tables V–X and an estimator (by
/// their names in scenario files: `"IX"`, `"kbjae"`, occlusion `"40% distal"`):
/// the RMSE and, for the compensation tables, the maximum hysteresis, each
/// `None` where the paper has no figure (kflex's own estimators, a bend or an
/// occlusion it did not measure). The uncompensated plant's figure in
/// Table VIII is the same for every occlusion (the plant sees no camera).
///
/// # Errors
/// [`ControlError::Unavailable`] where the embedded tables are malformed.
pub fn paper_figure(
    table: &str,
    estimator: &str,
    sheath_deg: f64,
    occlusion: &str,
) -> Result<(Option<PaperFigure>, Option<PaperFigure>)> {
    let section = match table {
        "V" => "table5_estimation_occlusion",
        "VI" => "table6_estimation_sheath",
        "VII" => "table7_estimation_both",
        "VIII" => "table8_compensation_occlusion",
        "IX" => "table9_compensation_sheath",
        "X" => "table10_compensation_both",
        _ => return Ok((None, None)),
    };
    let root: toml::Table = TABLES.parse().map_err(|e| bad(format!("{e}")))?;
    let t = root
        .get(section)
        .and_then(|v| v.as_table())
        .ok_or_else(|| bad(format!("no {section}")))?;
    // the column of the case: by occlusion, by bend, or by "occlusion, bend"
    let column = if let Some(names) = t.get("occlusion").and_then(|v| v.as_array()) {
        (sheath_deg == 0.0)
            .then(|| names.iter().position(|n| n.as_str() == Some(occlusion)))
            .flatten()
    } else if let Some(bends) = numbers(t.get("sheath_deg")) {
        (occlusion == "0%")
            .then(|| bends.iter().position(|s| (s - sheath_deg).abs() < 1e-9))
            .flatten()
    } else if let Some(cases) = t.get("case").and_then(|v| v.as_array()) {
        let name = format!("{occlusion}, {sheath_deg}");
        cases.iter().position(|n| n.as_str() == Some(name.as_str()))
    } else {
        None
    };
    let Some(column) = column else {
        return Ok((None, None));
    };
    let pick = |key: &str| -> Result<Option<PaperFigure>> {
        let Some(v) = t.get(key).and_then(|v| v.as_array()) else {
            return Ok(None);
        };
        // a row of [mean, std] per column, or one [mean, std] for all
        let pair = match numbers(Some(&toml::Value::Array(v.clone()))) {
            Some(single) => single,
            None => numbers(v.get(column))
                .ok_or_else(|| bad(format!("{section} {key}[{column}] is not [mean, std]")))?,
        };
        match pair.as_slice() {
            [mean, std] => Ok(Some(PaperFigure {
                mean: *mean,
                std: *std,
            })),
            _ => Err(bad(format!("{section} {key} is not [mean, std]"))),
        }
    };
    if section.contains("estimation") {
        Ok((pick(estimator)?, None))
    } else {
        Ok((
            pick(&format!("rmse_{estimator}"))?,
            pick(&format!("max_hysteresis_{estimator}"))?,
        ))
    }
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
        let (rmse, width) = paper_figure("IX", "none", 270.0, "0%").unwrap();
        let (rmse, width) = (rmse.unwrap(), width.unwrap());
        assert_eq!((rmse.mean, rmse.std), (21.9, 1.2));
        assert_eq!((width.mean, width.std), (18.4, 1.5));
        assert_eq!(
            paper_figure("IX", "none", 45.0, "0%").unwrap(),
            (None, None)
        );
    }

    #[test]
    fn reads_every_table_by_case_and_estimator() {
        let f = |t, e, s, o| {
            let (r, w) = paper_figure(t, e, s, o).unwrap();
            (r.map(|f| (f.mean, f.std)), w.map(|f| (f.mean, f.std)))
        };
        assert_eq!(
            f("V", "ibjae", 0.0, "40% distal"),
            (Some((27.1, 0.97)), None)
        );
        assert_eq!(f("VI", "kbjae", 270.0, "0%"), (Some((6.81, 3.97)), None));
        assert_eq!(
            f("VII", "lbhjae", 180.0, "40% distal"),
            (Some((5.755, 0.66)), None)
        );
        assert_eq!(
            f("VIII", "ibjae", 0.0, "20%"),
            (Some((3.05, 0.3)), Some((6.25, 1.3)))
        );
        // the uncompensated plant's one figure, for every occlusion
        assert_eq!(
            f("VIII", "none", 0.0, "40%"),
            (Some((7.84, 2.23)), Some((9.23, 0.73)))
        );
        assert_eq!(
            f("IX", "none", 180.0, "0%"),
            (Some((16.6, 3.7)), Some((18.3, 0.3)))
        );
        assert_eq!(f("X", "kbjae", 270.0, "40%"), (Some((13.02, 1.77)), None));
        // what the paper did not measure
        assert_eq!(f("IX", "lbhjae-adaptive", 90.0, "0%"), (None, None));
        assert_eq!(f("IX", "kbjae", 45.0, "0%"), (None, None));
        assert_eq!(f("VI", "kbjae", 90.0, "20%"), (None, None));
        assert_eq!(f("X", "none", 270.0, "40%"), (None, None));
        assert_eq!(f("XI", "kbjae", 0.0, "0%"), (None, None));
    }
}
