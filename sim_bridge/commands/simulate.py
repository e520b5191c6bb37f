"""`sim-bridge simulate SCENARIO`: one closed-loop run on truth navigation, a summary and a plot."""

from __future__ import annotations

import argparse

import numpy as np

from sim_bridge.faults import fault_active_intervals
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run, run_faults


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate", help="fly one closed-loop scenario run on truth navigation",
        description="Fly a scenario (id such as ch4, or a TOML path) in closed loop with its "
        "sensors and faults, the autopilot fed by the true state; print a summary, optionally plot.")
    p.add_argument("scenario", help="scenario id (ch4, ch5a, ch5b, ch5c, ch6) or a .toml path")
    p.add_argument("--seconds", type=float, default=None, help="run length (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--plot", metavar="FILE.png", default=None, help="write a figure of the run")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    sc = load_scenario(args.scenario)
    traj = run(sc, args.seed, seconds=args.seconds)
    h = -traj.z[:, 0]
    va = np.hypot(traj.z[:, 1], traj.z[:, 2])
    print(f"{sc.id}: {sc.title}")
    engine = "" if sc.sky.engine == "internal" else f" ({sc.sky.engine})"
    print(f"  truth {sc.truth.model}{engine}, {traj.t.size} steps of {sc.dt_s} s, seed {args.seed}")
    de = np.degrees(traj.u[:, 0])
    print(f"  altitude  min {h.min():8.2f} m    max {h.max():8.2f} m   "
          f"(command {sc.command.altitude_m} m)")
    speed = "gnd speed" if sc.sky.moving_air else "airspeed "      # |(u, w)| is over the ground
    print(f"  {speed} min {va.min():8.2f} m/s  max {va.max():8.2f} m/s "
          f"(airspeed command {sc.command.airspeed_mps} m/s)")
    print(f"  delta_e   min {de.min():8.2f} deg  max {de.max():8.2f} deg")
    print(f"  delta_t   min {traj.u[:, 1].min():8.3f}      max {traj.u[:, 1].max():8.3f}")
    flown = run_faults(sc, args.seed)                 # this run's draw of any varying fault
    chans = {ch.id: ch for ch in flown.faults}
    for fid, t0, t1 in fault_active_intervals(flown):
        ch = chans[fid]
        j = flown.faults.index(ch)
        peak = np.max(np.abs(traj.faults[:, j])) / ch.unit_scale
        print(f"  fault {fid:7s} on {ch.target:8s} {t0:6.2f}-{t1:6.2f} s  "
              f"(channel peak {peak:.3g} {ch.unit})")
    if args.plot:
        from sim_bridge.plots import plot_run

        print(f"  plot: {plot_run(traj, sc, args.plot)}")
    return 0
