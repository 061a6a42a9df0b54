//! Plant throughput. `cargo bench -p kflex-model --bench plant`
//!
//! * `analytic_tick`: one `Plant::step` with the analytic joint and the default
//!   20-element sheath at 180 deg (goal ≥ 200,000/s on one core).
//! * `rapier_tick`: one `Plant::step` with the rapier joint; the number of
//!   internal physics steps per tick is printed so steps/s can be derived (goal ≥ 10,000/s).

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use kflex_model::{Command, JointModelKind, Plant, PlantConfig, Trajectory};

fn commands(n: usize, dt: f64) -> Vec<Command> {
    let traj = Trajectory::paper().sampler().expect("paper trajectory");
    (0..n)
        .map(|k| Command {
            theta_c_deg: traj.sample(k as f64 * dt).theta_d_deg,
            translation_mm: 5.0,
        })
        .collect()
}

fn analytic(c: &mut Criterion) {
    let dt = 0.01;
    let cmds = commands(10_000, dt);
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 180.0,
        ..PlantConfig::default()
    })
    .expect("plant");
    let mut i = 0;
    c.bench_function("analytic_tick", |b| {
        b.iter(|| {
            i = (i + 1) % cmds.len();
            black_box(plant.step(black_box(cmds[i]), dt).expect("step"))
        })
    });
}

fn rapier(c: &mut Criterion) {
    let dt = 0.01;
    let cmds = commands(2_000, dt);
    let config = PlantConfig {
        sheath_deg: 180.0,
        joint_model: JointModelKind::Rapier,
        ..PlantConfig::default()
    };
    let mut plant = Plant::new(config).expect("plant");
    // steps per tick on the paper's input, and raw internal steps per second
    let start = Instant::now();
    for cmd in &cmds {
        plant.step(*cmd, dt).expect("step");
    }
    let secs = start.elapsed().as_secs_f64();
    let steps = plant.physics_steps();
    println!(
        "rapier: {} ticks, {} internal steps ({:.1}/tick), {:.0} internal steps/s, {:.0} ticks/s",
        cmds.len(),
        steps,
        steps as f64 / cmds.len() as f64,
        steps as f64 / secs,
        cmds.len() as f64 / secs
    );
    let mut i = 0;
    c.bench_function("rapier_tick", |b| {
        b.iter(|| {
            i = (i + 1) % cmds.len();
            black_box(plant.step(black_box(cmds[i]), dt).expect("step"))
        })
    });
}

criterion_group!(benches, analytic, rapier);
criterion_main!(benches);
