"""Probes of the robust monitor (docs/robustness.md, "which faults are ambiguous with which
disturbances"): one fault at a time injected from 20 s for 30 s into a fault-free real-sky flight
(moderate turbulence by default), flown with RJMRPF on the experiment's estimator; prints, per
probe and run, the faults the service would declare (its hysteresis) and when, after the onset.

    .venv/bin/python benchmarks/robust_probes.py [--world real-turbulence-faultfree] [--runs 0,1,2]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from fdir_service.paths import config_dir
from sim_bridge import campaign
from sim_bridge.scenario import load_scenario
from sim_bridge.yardstick import Hysteresis, declared

ONSET_S, DURATION_S, FLIGHT_S = 20.0, 30.0, 60.0

PROBES = {   # name: (world fault id, target, unit, shape, amplitude in unit; a ramp's in unit/s)
    "attitude step 1.7 deg (3 sigma)": ("theta", "theta", "deg", "step", 1.71),
    "barometer step 4.5 m (3 sigma)": ("baro", "baro_alt", "m", "step", 4.5),
    "GNSS altitude step 22.5 m (3 sigma)": ("gnss", "gnss_alt", "m", "step", 22.5),
    "gyro step 1 deg/s": ("q", "q", "deg/s", "step", 1.0),
    "gyro step 0.34 deg/s (3 sigma)": ("q", "q", "deg/s", "step", 0.34),
    "elevator step 2 deg": ("de", "delta_e", "deg", "step", 2.0),
    "elevator step 1 deg": ("de", "delta_e", "deg", "step", 1.0),
    "barometer ramp 0.1 m/s": ("baro", "baro_alt", "m", "ramp", 0.1),
    "elevator ramp 0.05 deg/s": ("de", "delta_e", "deg", "ramp", 0.05),
}


def fault_table(fid: str, target: str, unit: str, shape: str, amplitude: float) -> str:
    """The [[world.faults]] TOML of one probe."""
    peak = amplitude * DURATION_S if shape == "ramp" else amplitude    # a ramp peaks at its end
    return (f'\n[[world.faults]]\nid = "{fid}"\ntarget = "{target}"\nunit = "{unit}"\n'
            f'[[world.faults.profile]]\nshape = "{shape}"\nstart_s = {ONSET_S}\n'
            f"duration_s = {DURATION_S}\namplitude = {peak}\n")


def declarations(t: np.ndarray, P: np.ndarray, ids: tuple[str, ...], rule: Hysteresis) -> str:
    """'id +a..b s' of each declaration after the onset (times from the onset; no b: still standing
    at the end of the flight), in time order."""
    spans = []
    for j, fid in enumerate(ids):
        d = declared(t, P[:, j], rule).astype(np.int8)
        edge = np.diff(d, prepend=0, append=0)
        for a, b in zip(np.flatnonzero(edge == 1), np.flatnonzero(edge == -1), strict=True):
            if t[a] >= ONSET_S:
                end = f"{t[b - 1] - ONSET_S:.1f}" if b < t.size else ""
                spans.append((t[a] - ONSET_S, f"{fid} +{t[a] - ONSET_S:.2f}..{end} s"))
    return ", ".join(s for _, s in sorted(spans)) or "nothing"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="real-turbulence-faultfree", help="experiment id or .toml path")
    ap.add_argument("--runs", default="0,1,2")
    args = ap.parse_args(argv)
    runs = [int(r) for r in args.runs.split(",")]
    world = Path(args.world) if args.world.endswith(".toml") \
        else config_dir() / "experiments" / f"{args.world}.toml"
    base = world.read_text()
    rule = Hysteresis.of_service()
    head = " | ".join(f"run {r}" for r in runs)
    print(f"| fault (from {ONSET_S:g} s for {DURATION_S:g} s) | {head} |")
    print("|---|" + "---|" * len(runs))
    with tempfile.TemporaryDirectory() as tmp:
        for name, spec in PROBES.items():
            path = Path(tmp) / f"{args.world}-probe.toml"
            path.write_text(base + fault_table(*spec))
            sc = load_scenario(path)
            cells = []
            for r in runs:
                traj = campaign.fly(sc, "RJMRPF", r, seconds=FLIGHT_S)
                P = np.array([o.fault_probability for o in traj.outputs])
                t = np.array([o.t for o in traj.outputs])
                cells.append(declarations(t, P, traj.outputs[0].fault_ids, rule))
            print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
