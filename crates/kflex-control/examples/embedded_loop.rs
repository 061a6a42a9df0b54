//! The compensator embedded the way a robot's controller runs it: a
//! fixed-rate loop on its own clock (1 kHz), a camera at 30 Hz whose frames
//! arrive with latency, are sometimes dropped and sometimes late, and a
//! blackout (the camera covered for 0.5 s) that trips the watchdog.
//!
//! The estimator here is a **stand-in**: the plant's true angle at the
//! frame's capture time plus Gaussian noise, delivered when the frame
//! arrives. The real estimators (KBJAE, IBJAE and their Kalman fusion,
//! LBHJAE) live in `kflex-estimate`; a controller would feed the fused θ̂
//! to [`Compensator::step`] in the same place. The plant stands in for
//! the robot.
//!
//! Built with the embedding features only (no rapier3d, parry3d or image):
//! `make test-embedded` builds it (`cargo test --no-default-features`
//! builds every example). Run it with
//!
//! `cargo run --release -p kflex-control --no-default-features --example embedded_loop [SEED]`
//!
//! It prints, for sheath angles 0 and 270 deg, the RMSE and loop width of
//! the true angle against θ_d without compensation and with it (Eq. 3–5,
//! with and without G), and what the loop went through: frames used,
//! dropped, late, stale; ticks held by faults; watchdog trips.

use std::collections::VecDeque;

use kflex_control::{
    BacklashTerm, Compensator, CompensatorConfig, Fault, OpenLoopScenario, loop_width, rmse,
};
use kflex_model::{Command, Plant, PlantConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The control period, µs (1 kHz). The loop's clock counts whole ticks, so
/// no time drifts.
const TICK_US: u64 = 1_000;
/// The camera's frame period, µs (30 Hz).
const FRAME_US: u64 = 33_333;
/// Capture-to-estimate latency of a frame on time, µs.
const LATENCY_US: u64 = 45_000;
/// Chance that a frame never arrives.
const DROP_P: f64 = 0.08;
/// Chance that a frame arrives late, 30–150 ms after its usual time.
const LATE_P: f64 = 0.08;
/// The stand-in estimator's noise, deg (IBJAE's order).
const NOISE_DEG: f64 = 1.0;
/// The camera is covered from 20 s for 0.5 s (no frames at all).
const BLACKOUT_US: (u64, u64) = (20_000_000, 20_500_000);

/// A frame on its way: capture time, arrival time, the estimate it carries.
#[derive(Debug, Clone, Copy)]
struct Frame {
    captured_us: u64,
    arrives_us: u64,
    theta_hat_deg: f64,
}

/// What the loop went through.
#[derive(Debug, Default)]
struct Log {
    frames_used: usize,
    frames_dropped: usize,
    frames_late: usize,
    frames_stale: usize,
    fault_ticks: usize,
    watchdog_trips: usize,
}

/// One run: the paper's input at `sheath_deg`, `compensator` between θ_d
/// and the plant (`None`: θ_c = θ_d). Returns (RMSE, loop width) of the
/// true angle over the evaluated periods, and the log.
fn run(
    sheath_deg: f64,
    mut compensator: Option<Compensator>,
    seed: u64,
) -> Result<(f64, f64, Log), Box<dyn std::error::Error>> {
    let scenario = OpenLoopScenario::default();
    let sampler = scenario.trajectory.sampler()?;
    let mut plant = Plant::new(PlantConfig {
        sheath_deg,
        noise: None,
        ..PlantConfig::default()
    })?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, NOISE_DEG)?;
    let dt_s = TICK_US as f64 * 1e-6;
    // pre-roll to θ_d(0) as the open-loop scenario does, then the periods
    let pre_roll_us = (2.0 * scenario.pre_roll_s * 1e6) as u64;
    let end_us = pre_roll_us + (scenario.periods * scenario.period_s * 1e6) as u64;
    let start_deg = sampler.sample(0.0).theta_d_deg;

    // set-up allocates; the loop below does not grow these past their capacity
    let mut in_flight: VecDeque<Frame> = VecDeque::with_capacity(16);
    let ticks = ((end_us - pre_roll_us) / TICK_US) as usize;
    let (mut desired, mut rate, mut actual) = (
        Vec::with_capacity(ticks),
        Vec::with_capacity(ticks),
        Vec::with_capacity(ticks),
    );
    let mut log = Log::default();
    let mut last_used_capture_us = None;
    let mut was_watchdog = false;
    let mut next_frame_us = 0;

    let mut now_us = 0;
    while now_us < end_us {
        now_us += TICK_US;
        // θ_d from the master
        let (theta_d, theta_d_rate) = if now_us <= pre_roll_us {
            let u = (now_us as f64 / (0.5 * pre_roll_us as f64)).min(1.0);
            (
                start_deg * 0.5 * (1.0 - (std::f64::consts::PI * u).cos()),
                0.0,
            )
        } else {
            let s = sampler.sample((now_us - pre_roll_us) as f64 * 1e-6);
            (s.theta_d_deg, s.theta_d_rate_deg_per_s)
        };
        // the camera: capture now, deliver later (or never)
        if now_us >= next_frame_us {
            next_frame_us += FRAME_US;
            let blacked_out = (BLACKOUT_US.0..BLACKOUT_US.1).contains(&now_us);
            if blacked_out || rng.random_bool(DROP_P) {
                log.frames_dropped += 1;
            } else {
                let late_us = if rng.random_bool(LATE_P) {
                    log.frames_late += 1;
                    rng.random_range(30_000..150_000)
                } else {
                    0
                };
                if in_flight.len() < in_flight.capacity() {
                    in_flight.push_back(Frame {
                        captured_us: now_us,
                        arrives_us: now_us + LATENCY_US + late_us,
                        theta_hat_deg: plant.state().theta_a_deg + noise.sample(&mut rng),
                    });
                }
            }
        }
        // the newest frame that has arrived; older ones that arrive after it are stale
        let mut theta_hat = None;
        let mut newest = last_used_capture_us;
        in_flight.retain(|f| {
            if f.arrives_us > now_us {
                return true;
            }
            if newest.is_some_and(|n| f.captured_us <= n) {
                log.frames_stale += 1;
            } else {
                if theta_hat.is_some() {
                    log.frames_stale += 1; // superseded within this tick
                }
                newest = Some(f.captured_us);
                theta_hat = Some(f.theta_hat_deg);
            }
            false
        });
        if theta_hat.is_some() {
            log.frames_used += 1;
            last_used_capture_us = newest;
        }
        // the compensator, then the plant
        let theta_c = match compensator.as_mut() {
            Some(c) => {
                let out = c.step(theta_d, theta_hat, dt_s);
                let watchdog = matches!(out.fault, Some(Fault::Watchdog { .. }));
                log.watchdog_trips += usize::from(watchdog && !was_watchdog);
                was_watchdog = watchdog;
                log.fault_ticks += usize::from(out.fault.is_some());
                out.theta_c_deg
            }
            None => theta_d,
        };
        let state = plant.step(
            Command {
                theta_c_deg: theta_c,
                translation_mm: scenario.translation_mm,
            },
            dt_s,
        )?;
        if now_us > pre_roll_us {
            desired.push(theta_d);
            rate.push(theta_d_rate);
            actual.push(state.theta_a_deg);
        }
    }
    Ok((
        rmse(&desired, &actual)?,
        loop_width(&desired, &rate, &actual)?,
        log,
    ))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seed: u64 = std::env::args().nth(1).map_or(Ok(7), |a| a.parse())?;
    println!(
        "1 kHz loop, 30 Hz camera ({} ms latency, {:.0} % dropped, {:.0} % late, \
         0.5 s blackout at 20 s), stand-in estimate noise {NOISE_DEG} deg, seed {seed}",
        LATENCY_US / 1000,
        DROP_P * 100.0,
        LATE_P * 100.0
    );
    println!(
        "sheath  compensation     RMSE deg  loop width deg  frames used/dropped/late/stale  fault ticks  watchdog trips"
    );
    for sheath_deg in [0.0, 270.0] {
        let configs = [
            ("none", None),
            (
                "PID (G off)",
                Some(CompensatorConfig {
                    backlash_term: BacklashTerm::Off,
                    ..CompensatorConfig::default()
                }),
            ),
            ("PID + G (Eq. 5)", Some(CompensatorConfig::default())),
        ];
        for (name, config) in configs {
            let compensator = config.map(Compensator::new).transpose()?;
            let (e, w, log) = run(sheath_deg, compensator, seed)?;
            println!(
                "{sheath_deg:>6}  {name:<15}  {e:>8.2}  {w:>14.2}  {:>30}  {:>11}  {:>14}",
                format!(
                    "{}/{}/{}/{}",
                    log.frames_used, log.frames_dropped, log.frames_late, log.frames_stale
                ),
                log.fault_ticks,
                log.watchdog_trips
            );
        }
    }
    Ok(())
}
