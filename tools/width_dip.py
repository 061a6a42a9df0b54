#!/usr/bin/env python3
"""Why the nominal plant's loop narrows between 75 and 105 deg of bend.

    .venv/bin/python tools/width_dip.py

(`make test` or `make py-module` installs the `kflex` module into .venv.)
For each sheath angle it runs the paper's input on the nominal plant (the
shipped defaults, true angle, `OpenLoopScenario`'s defaults) and prints:

* the loop width, as `max_hysteresis_deg` reads it, and the command θ_d
  where the two branches lie furthest apart (the vertical gap between the
  falling and the rising branch of the last period, sampled every 0.5 deg
  of command);
* where, on the rising branch, the antagonist (tendon b, paid out while
  tendon a pulls the joint up) goes slack at its distal end, and the most
  tension it keeps on the way up.

The gap sampled this way reads within 0.03 deg of `max_hysteresis_deg`.

The widest gap lies low on the loop (θ_d near 18 deg) while the antagonist
is still taut there, and is the antagonist's drag: its pretension, eaten
by the sheath's path change as the bend grows, falls with the bend, and so
does the gap. Above the point where the antagonist goes slack the rising
branch climbs freely; that point moves down the rising branch as the bend
grows, and once it passes below the old widest point (beyond 105 deg) the
widest gap moves up the loop and grows with the bend again. The width is
the larger of the two, and dips where the first falls before the second
takes over (CALIBRATION.md, "What is not met").
"""
import numpy as np

import kflex

SHEATHS = [0, 15, 30, 45, 60, 75, 90, 105, 120, 135, 150, 165, 180]
SLACK_N = 0.05  # a tension below this, N, counts as slack


def row(sheath_deg):
    cfg = kflex.PlantConfig()
    cfg.sheath_deg = float(sheath_deg)
    cfg.noise = None
    scenario = kflex.OpenLoopScenario()
    width = scenario.run(kflex.Plant(cfg)).metrics()["max_hysteresis_deg"]
    # the same run, tick by tick, with the tendons' tensions
    dt, period = scenario.dt_s, scenario.period_s
    t = np.arange(1, round((scenario.pre_roll_s + scenario.periods * period) / dt) + 1) * dt
    trajectory = kflex.Trajectory.paper()
    theta_d, rate = (np.asarray(a) for a in trajectory.sample(t - scenario.pre_roll_s))
    theta_d = np.where(t > scenario.pre_roll_s, theta_d, theta_d[0])
    out = kflex.Plant(cfg).run(theta_d, np.full_like(t, scenario.translation_mm), dt)
    last = t > t[-1] - period
    up, down = last & (rate > 0), last & (rate < 0)
    grid = np.arange(1.0, 49.5, 0.5)

    def branch(mask):
        order = np.argsort(theta_d[mask])
        return np.interp(grid, theta_d[mask][order], out["theta_a_deg"][mask][order])

    gap = branch(down) - branch(up)
    b = out["tensions.b_distal_n"]
    slack = theta_d[up & (b < SLACK_N)]
    return (
        width,
        float(np.max(gap)),
        float(grid[np.argmax(gap)]),
        float(slack.min()) if len(slack) else float("nan"),
        float(b[up].max()),
    )


def main():
    print("| sheath (deg) | loop width (deg) | widest gap (deg) | at θ_d (deg) "
          "| antagonist slack on the rise from θ_d (deg) | its most tension on the rise (N) |")
    print("|---|---|---|---|---|---|")
    for s in SHEATHS:
        width, gap, at, slack, most = row(s)
        slack = "never" if np.isnan(slack) else f"{slack:.1f}"
        print(f"| {s} | {width:.2f} | {gap:.2f} | {at:.1f} | {slack} | {most:.2f} |")


if __name__ == "__main__":
    main()
