//! Prints the fusion filters' RMSE against the plant's true angle with
//! synthetic KBJAE and IBJAE sensors (see `tests/common/fusion_scenario.rs`
//! for how they are made), on the paper's input:
//! `cargo run --release -p kflex-estimate --example fusion_table`.

#[path = "../tests/common/fusion_scenario.rs"]
mod scenario;

use scenario::{Scenario, table_row};

fn main() {
    println!(
        "| sheath (deg) | occlusion | IBJAE confidence | KBJAE alone | IBJAE alone | paper, as run | paper, as written | adaptive |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (sheath_deg, distal_occlusion, confidence) in [
        (0.0, false, false),
        (270.0, false, false),
        (0.0, true, false),
        (270.0, true, false),
        (0.0, true, true),
        (270.0, true, true),
    ] {
        let mut rows = Vec::new();
        for seed in 0..3 {
            rows.push(table_row(Scenario {
                sheath_deg,
                distal_occlusion,
                confidence,
                seed,
            }));
        }
        let mean = |i: usize| rows.iter().map(|r| r[i]).sum::<f64>() / rows.len() as f64;
        println!(
            "| {sheath_deg} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            if distal_occlusion {
                "40 % distal"
            } else {
                "none"
            },
            if confidence { "given" } else { "-" },
            mean(0),
            mean(1),
            mean(2),
            mean(3),
            mean(4)
        );
    }
}
