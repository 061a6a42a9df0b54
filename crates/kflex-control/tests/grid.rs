//! The grid of the paper's experiments (`ExperimentGrid`) and its scenario
//! files in `assets/scenarios/`.

use std::path::Path;
use std::sync::Mutex;

use kflex_control::{
    AngleEstimator, Case, CaseKind, ControlError, EstimatorKind, ExperimentGrid, NoisyTruth,
    OcclusionCase, OpenLoopScenario, Record,
};
use kflex_model::Background;

fn scenario_file(name: &str) -> ExperimentGrid {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/scenarios")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_scenario_files_are_the_papers_grid() {
    let paper = ExperimentGrid::paper();
    assert_eq!(scenario_file("paper.toml"), paper);
    assert_eq!(paper.cases.len(), 22);
    let mut from_tables = Vec::new();
    for table in ["V", "VI", "VII", "VIII", "IX", "X"] {
        let grid = scenario_file(&format!("table_{}.toml", table.to_lowercase()));
        assert_eq!(grid, ExperimentGrid::paper_table(table), "table {table}");
        assert!(grid.cases.iter().all(|c| c.table == table));
        from_tables.extend(grid.cases);
    }
    assert_eq!(from_tables, paper.cases);
    // the paper's cases: Table V at sheath 0 over the four occlusions, VII's three pairs
    let v: Vec<OcclusionCase> = ExperimentGrid::paper_table("V")
        .cases
        .iter()
        .map(|c| c.occlusion)
        .collect();
    assert_eq!(
        v,
        [
            OcclusionCase::None,
            OcclusionCase::Middle20,
            OcclusionCase::Middle40,
            OcclusionCase::Distal40
        ]
    );
    let x: Vec<(f64, &str)> = ExperimentGrid::paper_table("X")
        .cases
        .iter()
        .map(|c| (c.sheath_deg, c.occlusion.name()))
        .collect();
    assert_eq!(
        x,
        [(270.0, "40%"), (180.0, "40% distal"), (270.0, "40% distal")]
    );
    let distal = OcclusionCase::Distal40.occlusion().unwrap();
    assert_eq!((distal.fraction, distal.position), (0.4, 1.0));
    assert!(OcclusionCase::None.occlusion().is_none());
}

#[test]
fn a_malformed_scenario_names_the_field() {
    for (text, names) in [
        ("repeatz = 3", "repeatz"),
        (
            "[[cases]]\ntable = \"V\"\nkind = \"estimation\"\nsheath_deg = 0.0\nocclusion = \"30%\"",
            "30%",
        ),
        ("estimators = [\"kbjae\", \"oracle\"]", "oracle"),
        (
            "[[cases]]\ntable = \"V\"\nkind = \"estimation\"\nocclusion = \"0%\"",
            "sheath_deg",
        ),
    ] {
        let err = toml::from_str::<ExperimentGrid>(text)
            .unwrap_err()
            .to_string();
        assert!(err.contains(names), "{text:?}: {err}");
        // the line is named too
        assert!(err.contains("line"), "{err}");
    }
}

/// A small grid: one estimation case with distal tape, one compensation
/// case; the uncompensated plant and a stand-in estimator; two repeats of a
/// short input.
fn small() -> ExperimentGrid {
    let mut grid = ExperimentGrid {
        cases: vec![
            Case {
                table: "V".into(),
                kind: CaseKind::Estimation,
                sheath_deg: 0.0,
                occlusion: OcclusionCase::Distal40,
            },
            Case {
                table: "VIII".into(),
                kind: CaseKind::Compensation,
                sheath_deg: 0.0,
                occlusion: OcclusionCase::None,
            },
        ],
        estimators: vec![EstimatorKind::None, EstimatorKind::Kbjae],
        repeats: 2,
        ..ExperimentGrid::paper()
    };
    grid.scenario.motion = OpenLoopScenario {
        periods: 2.0,
        ..OpenLoopScenario::default()
    };
    grid
}

fn run(grid: &ExperimentGrid, jobs: usize) -> (Vec<Record>, Vec<(usize, usize)>) {
    let made = Mutex::new(Vec::new());
    let make = |kind: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        made.lock().unwrap().push(kind);
        Ok(Box::new(NoisyTruth::new(1.0, 9)?))
    };
    let steps = Mutex::new(Vec::new());
    let records = grid
        .run(jobs, &make, &|done, total| {
            steps.lock().unwrap().push((done, total))
        })
        .unwrap();
    // one estimator per run; none for the uncompensated plant
    assert_eq!(made.into_inner().unwrap(), [EstimatorKind::Kbjae; 4]);
    let mut steps = steps.into_inner().unwrap();
    steps.sort_unstable();
    (records, steps)
}

#[test]
fn the_grid_runs_every_case_with_every_estimator() {
    let grid = small();
    let (records, steps) = run(&grid, 1);
    // no estimation record for "none"
    let keys: Vec<(CaseKind, EstimatorKind)> =
        records.iter().map(|r| (r.case.kind, r.estimator)).collect();
    assert_eq!(
        keys,
        [
            (CaseKind::Estimation, EstimatorKind::Kbjae),
            (CaseKind::Compensation, EstimatorKind::None),
            (CaseKind::Compensation, EstimatorKind::Kbjae),
        ]
    );
    assert_eq!(steps, [(1, 3), (2, 3), (3, 3)]);
    for r in &records {
        assert_eq!(
            r.repeats,
            [(2020, Background::Colon), (2021, Background::Stomach)]
        );
        assert_eq!(
            r.hysteresis.is_some(),
            r.case.kind == CaseKind::Compensation
        );
        assert!(r.rmse_deg.mean.is_finite() && r.rmse_deg.std >= 0.0);
    }
    // the stand-in estimates the true angle to within its noise (and the
    // time a 30 Hz camera takes); compensation on it cuts the RMSE
    assert!(records[0].rmse_deg.mean < 2.0, "{:?}", records[0].rmse_deg);
    let (none, comp) = (records[1].rmse_deg.mean, records[2].rmse_deg.mean);
    assert!(comp < 0.5 * none, "{comp} against {none}");
    let [width, p2p, loss] = records[1].hysteresis.unwrap();
    assert!(width.mean > 5.0 && p2p.mean > width.mean && loss.mean > 0.0);
    // deterministic in the seeds, and the same on two threads
    assert_eq!(run(&grid, 1).0, records);
    assert_eq!(run(&grid, 2), (records, steps));
}

/// A case that two tables hold (the paper's Tables V and VI both hold the
/// straight sheath without tape) is one run: made and run once, its figures
/// under each table, each in its own place in the grid's order, and handed
/// to `on_run` under each.
#[test]
fn a_case_two_tables_hold_runs_once() {
    let mut grid = small();
    let mut again = grid.cases[0].clone();
    again.table = "VI".into();
    let mut compensated = grid.cases[1].clone();
    compensated.table = "IX".into();
    // V, VIII, VI (V's case again), IX (VIII's case again)
    grid.cases.push(again);
    grid.cases.push(compensated);
    // three runs (V and VI's; VIII and IX's, without and with KBJAE)
    // where six jobs are listed
    assert_eq!(grid.job_count(), 3);
    let made = Mutex::new(0);
    let make = |_kind: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        *made.lock().unwrap() += 1;
        Ok(Box::new(NoisyTruth::new(1.0, 9)?))
    };
    let handed = Mutex::new(Vec::new());
    let steps = Mutex::new(Vec::new());
    for jobs in [1, 2] {
        *made.lock().unwrap() = 0;
        handed.lock().unwrap().clear();
        steps.lock().unwrap().clear();
        let records = grid
            .run_with(
                jobs,
                &make,
                &|done, total| steps.lock().unwrap().push((done, total)),
                &|run| {
                    handed
                        .lock()
                        .unwrap()
                        .push((run.case.table.clone(), run.seed));
                    Ok(())
                },
            )
            .unwrap();
        // KBJAE made once a repeat for V and VI's run, once a repeat for
        // its compensation run: four, as without the copies
        assert_eq!(*made.lock().unwrap(), 4, "{jobs} threads");
        let tables: Vec<&str> = records.iter().map(|r| r.case.table.as_str()).collect();
        assert_eq!(tables, ["V", "VIII", "VIII", "VI", "IX", "IX"]);
        // the copies' figures are the originals'
        for (copy, original) in [(3, 0), (4, 1), (5, 2)] {
            let (a, b) = (&records[copy], &records[original]);
            assert_eq!(
                (a.estimator, a.rmse_deg, a.hysteresis, &a.repeats),
                (b.estimator, b.rmse_deg, b.hysteresis, &b.repeats)
            );
            assert!(a.case.same_run(&b.case) && a.case != b.case);
        }
        // every run handed over under each table that holds it
        let mut handed = handed.lock().unwrap().clone();
        handed.sort();
        let per_table = |t: &str| handed.iter().filter(|h| h.0 == t).count();
        assert_eq!(
            ["V", "VI", "VIII", "IX"].map(per_table),
            [2, 2, 4, 4],
            "{handed:?}"
        );
        // the progress counts the six jobs
        let mut steps = steps.lock().unwrap().clone();
        steps.sort_unstable();
        assert_eq!(steps.last(), Some(&(6, 6)));
    }
    // the copies give the same records as the grid without them
    let (alone, _) = run(&small(), 1);
    let with = grid.run(1, &make, &|_, _| {}).unwrap();
    assert_eq!(&with[..3], &alone[..]);
}

#[test]
fn bad_settings_are_named_before_any_run() {
    let named = |grid: ExperimentGrid| {
        let make = |_kind: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
            panic!("no run may start")
        };
        grid.run(2, &make, &|_, _| {}).unwrap_err()
    };
    let e = named(ExperimentGrid {
        repeats: 0,
        ..small()
    });
    assert_eq!(e.range().map(|r| r.name), Some("repeats"));
    let e = named(ExperimentGrid {
        spread: f64::NAN,
        ..small()
    });
    assert_eq!(e.range().map(|r| r.name), Some("spread"));
    let mut grid = small();
    grid.cases[1].sheath_deg = -5.0;
    let e = named(grid);
    assert_eq!(e.range().map(|r| r.name), Some("sheath_deg"));
    // the case is named, and the bound is the plant's own (its sheath's
    // friction limits the wrap below 3600 deg), as the plant would say it
    assert!(
        e.to_string()
            .starts_with("case 2 (VIII_-5deg_0pct): sheath_deg = -5 "),
        "{e}"
    );
    let mut grid = small();
    grid.cases[0].sheath_deg = 3000.0;
    let e = named(grid.clone());
    let max = grid.plant.sheath.max_sheath_deg();
    assert!(max < 3000.0, "the default plant's limit binds: {max}");
    assert_eq!(e.range().map(|r| r.bounds.max), Some(max), "{e}");
    let e = named(ExperimentGrid {
        estimators: vec![],
        ..small()
    });
    assert!(matches!(e, ControlError::NotEnoughData { .. }), "{e}");
    let mut grid = small();
    grid.scenario.camera.rate_hz = -1.0;
    assert_eq!(named(grid).range().map(|r| r.name), Some("camera.rate_hz"));
}

#[test]
fn the_first_failure_in_the_grids_order_stops_it() {
    // the estimator of the second pair fails to load
    for jobs in [1, 2] {
        let count = Mutex::new(0);
        let make = |_kind: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
            let mut n = count.lock().unwrap();
            *n += 1;
            if *n == 3 {
                return Err(ControlError::NotEnoughData {
                    metric: "model file",
                    needed: "a trained model",
                    got: 0,
                });
            }
            Ok(Box::new(NoisyTruth::new(1.0, 9)?))
        };
        let e = small().run(jobs, &make, &|_, _| {}).unwrap_err();
        assert!(e.to_string().contains("model file"), "{e}");
    }
}

/// Stand-ins for two estimators: the true angle with 0.5 deg of noise for
/// KBJAE, 3 deg for any other.
fn two_stand_ins(kind: EstimatorKind) -> kflex_control::Result<Box<dyn AngleEstimator>> {
    let sigma = if kind == EstimatorKind::Kbjae {
        0.5
    } else {
        3.0
    };
    Ok(Box::new(NoisyTruth::new(sigma, 4)?))
}

#[test]
fn an_estimation_cases_estimators_share_its_runs() {
    // a stand-in per kind, with its own noise: together on one run they
    // read the same as each alone (the open loop does not depend on them)
    let make = two_stand_ins;
    let grid = |estimators: Vec<EstimatorKind>| ExperimentGrid {
        cases: vec![small().cases[0].clone()],
        estimators,
        ..small()
    };
    let both = grid(vec![EstimatorKind::Kbjae, EstimatorKind::Ibjae])
        .run(1, &make, &|_, _| {})
        .unwrap();
    let alone: Vec<Record> = [EstimatorKind::Kbjae, EstimatorKind::Ibjae]
        .into_iter()
        .flat_map(|e| grid(vec![e]).run(1, &make, &|_, _| {}).unwrap())
        .collect();
    assert_eq!(both, alone);
    assert!(
        both[1].rmse_deg.mean > 2.0 * both[0].rmse_deg.mean,
        "{both:?}"
    );
}

/// `run_with` hands over every run as it ends: each case's repeats, the
/// estimators on it and each one's estimates beside the trace, whose own
/// estimate is the first estimator's; the records are `run`'s; an error of
/// the hook stops the grid.
#[test]
fn every_run_is_handed_over_with_each_estimators_estimates() {
    let make = two_stand_ins;
    let grid = ExperimentGrid {
        estimators: vec![
            EstimatorKind::None,
            EstimatorKind::Kbjae,
            EstimatorKind::Ibjae,
        ],
        ..small()
    };
    let seen = Mutex::new(Vec::new());
    let records = grid
        .run_with(2, &make, &|_, _| {}, &|run| {
            let n = run.trace.trace.theta_a_deg.len();
            assert_eq!(run.estimates.len(), run.estimators.len());
            for e in run.estimates {
                assert_eq!(e.len(), n);
            }
            assert_eq!(run.estimates[0], &run.trace.theta_hat_deg[..]);
            // what went into each estimate, aligned with it: the stand-in
            // cameras tell their reading on the ticks that had a frame
            assert_eq!(run.details.len(), run.estimators.len());
            assert_eq!(run.details[0], &run.trace.details[..]);
            for ((d, e), kind) in run.details.iter().zip(run.estimates).zip(run.estimators) {
                assert_eq!(d.len(), n);
                let read: Vec<usize> = (0..n).filter(|&k| d[k].ibjae_deg.is_some()).collect();
                for &k in &read {
                    assert_eq!(d[k].ibjae_deg, e[k]);
                }
                if *kind != EstimatorKind::None {
                    // a 30 Hz camera over 100 Hz ticks, less what it drops
                    let share = read.len() as f64 / n as f64;
                    assert!(share > 0.2 && share <= 0.34, "{share}");
                } else {
                    assert!(read.is_empty());
                }
            }
            // the estimation run's second estimator reads the same truth with more noise
            if run.estimators.len() == 2 {
                let err = |e: &[Option<f64>]| {
                    e.iter()
                        .zip(&run.trace.trace.theta_a_deg)
                        .filter_map(|(h, a)| h.map(|h| (h - a).abs()))
                        .sum::<f64>()
                };
                assert!(err(run.estimates[1]) > 2.0 * err(run.estimates[0]));
            }
            assert_eq!(
                run.scenario.frames.occlusion,
                run.case.occlusion.occlusion()
            );
            seen.lock().unwrap().push((
                run.case.table.clone(),
                run.estimators.to_vec(),
                run.seed,
                run.background,
            ));
            Ok(())
        })
        .unwrap();
    let mut seen = seen.into_inner().unwrap();
    seen.sort_by_key(|(t, e, s, _)| (t.clone(), e.len(), *s, e.first().map(|k| k.name())));
    use EstimatorKind::{Ibjae, Kbjae, None as Plain};
    let expected = [
        ("V", vec![Kbjae, Ibjae], 2020, Background::Colon),
        ("V", vec![Kbjae, Ibjae], 2021, Background::Stomach),
        ("VIII", vec![Ibjae], 2020, Background::Colon),
        ("VIII", vec![Kbjae], 2020, Background::Colon),
        ("VIII", vec![Plain], 2020, Background::Colon),
        ("VIII", vec![Ibjae], 2021, Background::Stomach),
        ("VIII", vec![Kbjae], 2021, Background::Stomach),
        ("VIII", vec![Plain], 2021, Background::Stomach),
    ];
    let mut expected: Vec<(String, Vec<EstimatorKind>, u64, Background)> = expected
        .into_iter()
        .map(|(t, e, s, b)| (t.to_string(), e, s, b))
        .collect();
    expected.sort_by_key(|(t, e, s, _)| (t.clone(), e.len(), *s, e.first().map(|k| k.name())));
    assert_eq!(seen, expected);
    assert_eq!(records, grid.run(1, &make, &|_, _| {}).unwrap());
    // the hook's error stops the grid
    let err = grid
        .run_with(1, &make, &|_, _| {}, &|_| {
            Err(ControlError::Unavailable {
                what: "a full disk".into(),
            })
        })
        .unwrap_err();
    assert!(err.to_string().contains("a full disk"), "{err}");
    // a stop asked for: the run in progress ends, no further run starts
    let stop = std::sync::atomic::AtomicBool::new(false);
    let runs = std::sync::atomic::AtomicUsize::new(0);
    let err = grid
        .run_until(
            1,
            &make,
            &|_, _| {},
            &|_| {
                runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                Ok(())
            },
            &stop,
        )
        .unwrap_err();
    assert_eq!(err, ControlError::Interrupted);
    assert_eq!(runs.into_inner(), 1);
}

#[test]
fn the_quick_grid_keeps_each_tables_first_and_last_case() {
    let quick = ExperimentGrid::paper().quick();
    let cases: Vec<(String, f64, &str)> = quick
        .cases
        .iter()
        .map(|c| (c.table.clone(), c.sheath_deg, c.occlusion.name()))
        .collect();
    let expected: Vec<(String, f64, &str)> = [
        ("V", 0.0, "0%"),
        ("V", 0.0, "40% distal"),
        ("VI", 0.0, "0%"),
        ("VI", 270.0, "0%"),
        ("VII", 270.0, "40%"),
        ("VII", 270.0, "40% distal"),
        ("VIII", 0.0, "0%"),
        ("VIII", 0.0, "40% distal"),
        ("IX", 0.0, "0%"),
        ("IX", 270.0, "0%"),
        ("X", 270.0, "40%"),
        ("X", 270.0, "40% distal"),
    ]
    .iter()
    .map(|&(t, s, o)| (t.to_string(), s, o))
    .collect();
    assert_eq!(cases, expected);
    assert_eq!(quick.repeats, 1);
    assert_eq!(quick.scenario.motion.periods, 1.0);
    assert_eq!(quick.estimators, ExperimentGrid::paper().estimators);
    // a table of one case keeps it once
    let one = ExperimentGrid::paper_table("IX");
    let one = ExperimentGrid {
        cases: one.cases[..1].to_vec(),
        ..one
    };
    assert_eq!(one.quick().cases.len(), 1);
}

#[test]
fn an_estimator_named_twice_runs_once() {
    let make = |_: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        Ok(Box::new(NoisyTruth::new(1.0, 9)?))
    };
    let twice = ExperimentGrid {
        estimators: vec![
            EstimatorKind::Kbjae,
            EstimatorKind::None,
            EstimatorKind::Kbjae,
        ],
        ..small()
    };
    let once = ExperimentGrid {
        estimators: vec![EstimatorKind::Kbjae, EstimatorKind::None],
        ..small()
    };
    let run = |g: &ExperimentGrid| g.run(1, &make, &|_, _| {}).unwrap();
    assert_eq!(run(&twice), run(&once));
    assert_eq!(run(&once).len(), 3);
}

#[test]
fn estimation_cases_with_only_the_uncompensated_plant_are_nothing_to_run() {
    let grid = ExperimentGrid {
        estimators: vec![EstimatorKind::None],
        ..ExperimentGrid::paper_table("V")
    };
    let make = |_: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        unreachable!("nothing is made before the grid is checked")
    };
    let err = grid.run(1, &make, &|_, _| {}).unwrap_err();
    assert!(
        matches!(
            err,
            ControlError::NotEnoughData {
                metric: "experiment grid",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("nothing to run"), "{err}");
    // a compensation case gives "none" a run
    assert!(
        ExperimentGrid {
            estimators: vec![EstimatorKind::None],
            ..ExperimentGrid::paper_table("IX")
        }
        .validate()
        .is_ok()
    );
}

#[test]
fn cases_that_would_share_file_names_are_refused_before_any_run() {
    let make = |_: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        unreachable!("nothing is made before the grid is checked")
    };
    let mut grid = small();
    // the compensation case again, as an estimation case of the same table
    let mut twin = grid.cases[1].clone();
    twin.kind = CaseKind::Estimation;
    grid.cases.push(twin);
    let err = grid.run(1, &make, &|_, _| {}).unwrap_err();
    assert!(
        matches!(&err, ControlError::SharedCaseName { first: 2, second: 3, stem } if stem == "VIII_0deg_0pct"),
        "{err}"
    );
    assert!(err.to_string().contains("table names that differ"), "{err}");
    // the same case twice too
    let mut grid = small();
    grid.cases.push(grid.cases[0].clone());
    assert!(matches!(
        grid.validate(),
        Err(ControlError::SharedCaseName {
            first: 1,
            second: 3,
            ..
        })
    ));
    // names that differ only in case, or in characters file names replace
    for (table, twin_table) in [("VIII", "viii"), ("VIII a", "VIII_a")] {
        let mut grid = small();
        grid.cases[1].table = table.into();
        let mut twin = grid.cases[1].clone();
        twin.table = twin_table.into();
        grid.cases.push(twin);
        assert!(
            matches!(
                grid.validate(),
                Err(ControlError::SharedCaseName {
                    first: 2,
                    second: 3,
                    ..
                })
            ),
            "{twin_table:?}"
        );
    }
    // every scenario file names its cases apart
    for name in ["paper.toml", "table_ix.toml", "table_v.toml"] {
        scenario_file(name).validate().unwrap();
    }
}

#[test]
fn a_seed_whose_repeats_would_wrap_past_the_largest_is_refused() {
    let grid = |seed: u64, repeats: u32| ExperimentGrid {
        seed,
        repeats,
        ..small()
    };
    // three repeats run on seed, seed + 1, seed + 2: the largest base is 2⁶⁴ − 3
    assert!(grid(u64::MAX - 2, 3).validate().is_ok());
    assert!(grid(u64::MAX, 1).validate().is_ok());
    let err = grid(u64::MAX - 1, 3).validate().unwrap_err();
    assert!(
        matches!(
            err,
            ControlError::SeedOverflow {
                seed,
                repeats: 3,
                largest_base
            } if seed == u64::MAX - 1 && largest_base == u64::MAX - 2
        ),
        "{err}"
    );
    assert!(err.to_string().contains("18446744073709551613"), "{err}");
}

#[test]
fn an_estimator_that_no_frame_reaches_is_named_not_a_bare_metric() {
    // every frame lost: the camera's stand-in never gives an estimate
    let mut grid = ExperimentGrid {
        cases: vec![small().cases[0].clone()],
        estimators: vec![EstimatorKind::Ibjae],
        repeats: 1,
        ..small()
    };
    grid.scenario.camera.drop_probability = 1.0;
    let make = |_: EstimatorKind| -> kflex_control::Result<Box<dyn AngleEstimator>> {
        Ok(Box::new(NoisyTruth::new(1.0, 9)?))
    };
    let err = grid.run(1, &make, &|_, _| {}).unwrap_err();
    assert!(
        matches!(&err, ControlError::NoEstimate { estimator: "ibjae", case, seed: 2020 } if case == "V_0deg_40pct-distal"),
        "{err}"
    );
    assert!(err.to_string().contains("drop_probability"), "{err}");
}
