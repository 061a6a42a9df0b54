#!/usr/bin/env python3
"""Where the nominal plant's loop is widest, and why its width grows with the
bend through the point where that moves.

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

The loop has two wide places. Low on it (θ_d near 18 deg) the antagonist
is still taut on the rise, and the gap there is its drag; its pretension,
eaten by the sheath's path change as the bend grows, falls with the bend,
so this gap grows ever more slowly and would fall. Above the point where
the antagonist goes slack the rising branch climbs without it; that point
moves down the rising branch as the bend grows, and once it lies below the
low wide place the widest gap moves up the loop (θ_d 22-28 deg), where it
grows with the bend. The width is the larger of the two. On the plant
shipped until the last refit of 2026-11-29 (pretension 3 N, path change
-0.103 mm/rad) the low gap began to fall before the high one took over,
and the width dipped by 2.3 % from 75 to 105 deg; on today's (2.2 N,
-0.077 mm/rad) the antagonist goes slack lower on the rise, the high gap
takes over at 90 deg while the low one still grows, and the width grows at
every step (CALIBRATION.md, "Loop shape").
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
