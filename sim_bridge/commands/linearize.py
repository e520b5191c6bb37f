"""`sim-bridge linearize`: trim the Aerosonde and print the discrete (ZOH) F, B."""

from __future__ import annotations

import argparse
import json

import numpy as np

from fdir_service.airframe import STATE_NAMES, linearize, load_airframe
from fdir_service.airframe.linearize import PRINTED_B, PRINTED_F


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "linearize", help="trim the airframe and print the discrete linear model",
        description="Trim the Aerosonde at the given airspeed and altitude (level flight), "
        "linearise numerically and discretise with a zero-order hold. State order "
        "[p_d, u, w, theta, q], inputs [delta_e, delta_t].")
    p.add_argument("--airspeed", type=float, default=40.0, help="trim airspeed, m/s (default 40)")
    p.add_argument("--altitude", type=float, default=500.0, help="trim altitude, m (default 500)")
    p.add_argument("--dt", type=float, default=0.05, help="sample time, s (default 0.05)")
    p.add_argument("--airframe", default=None, help="airframe TOML (default config/aerosonde.toml)")
    p.add_argument("--json", action="store_true", help="print JSON {trim, F, B} instead of tables")
    p.set_defaults(func=main)


def _matrix(name: str, M: np.ndarray, cols: tuple[str, ...]) -> str:
    lines = [f"{name}:", "          " + "".join(f"{c:>10s}" for c in cols)]
    for r, row in zip(STATE_NAMES, M, strict=True):
        lines.append(f"  {r:>8s}" + "".join(f"{v:10.4f}" for v in row))
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    params = load_airframe(args.airframe)
    model = linearize(params, args.airspeed, args.altitude, args.dt)
    if args.json:
        print(json.dumps({"trim": model.trim.as_dict(), "F": model.F.tolist(), "B": model.B.tolist(),
                          "state_order": list(STATE_NAMES), "input_order": ["delta_e", "delta_t"],
                          "dt_s": args.dt}, indent=2))
        return 0
    print(f"Trim at {args.airspeed} m/s, {args.altitude} m, level flight (m = {params.m} kg, "
          f"rho = {params.rho} kg/m^3):")
    for k, v in model.trim.as_dict().items():
        print(f"  {k:14s} {v:.6g}")
    ev = np.linalg.eigvals(model.A)
    print("Continuous eigenvalues: " + ", ".join(f"{e.real:.3f}{e.imag:+.3f}j" for e in sorted(
        ev, key=lambda e: (e.real, e.imag))))
    inputs = ("delta_e", "delta_t")
    print(_matrix(f"F (discrete, ZOH, dt = {args.dt} s)", model.F, STATE_NAMES))
    print(_matrix("B", model.B, inputs))
    if abs(args.dt - 0.05) < 1e-12:
        print(_matrix("F printed in the thesis (eq. 4.25)", PRINTED_F, STATE_NAMES))
        print(_matrix("B printed in the thesis (eq. 4.26)", PRINTED_B, inputs))
        print(_matrix("F derived - printed", model.F - PRINTED_F, STATE_NAMES))
        print(_matrix("B derived - printed", model.B - PRINTED_B, inputs))
        worst = max(np.abs(model.F - PRINTED_F).max(), np.abs(model.B - PRINTED_B).max())
        print(f"largest |derived - printed| = {worst:.4f} (the printed model is rounded to 0.01)")
    else:
        print("(the thesis printed its model at dt = 0.05 s only; no comparison)")
    return 0
