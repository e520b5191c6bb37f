"""Open-loop quality check of the filters against the thesis's tables (synthetic data, no simulator).

    python -m sim_bridge.openloop ch5a RJMRPF,JMRPF,RPF --runs 20 [--sigma-x-scale 0.2236]

For each run: `synthetic.generate` (truth at trim, trim input, the scenario's faults), every named
filter on the same data; prints RMSE_k of each fault estimate at 10.05, 20.05, 30.05, 40.05 s and
its time average ("mean"), in the fault's unit, beside the thesis's values
(config/experiments/thesis_tables.json). `--sigma-x-scale` multiplies the estimator's parts.sigma_x
(0.2236 = sqrt(dt): the per-step noise if the thesis's values were continuous-time intensities).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from fdir_service.estimation.factory import build_filter
from sim_bridge.report import thesis_tables
from sim_bridge.scenario import load_scenario
from sim_bridge.synthetic import generate

INSTANTS = (10.05, 20.05, 30.05, 40.05)


def open_loop_rmse(scenario_id: str, filters: list[str], runs: int = 20, sigma_x_scale: float = 1.0,
                   seed: int = 1234, filter_seed: int = 99) -> dict[str, dict[str, dict[str, float]]]:
    """{filter: {"f_<id>": {"10.05": ..., "20.05": ..., "30.05": ..., "40.05": ..., "mean": ...}}}."""
    sc = load_scenario(scenario_id)
    if sigma_x_scale != 1.0:
        parts = sc.estimator.settings
        parts = dataclasses.replace(parts, sigma_x=tuple(np.array(parts.sigma_x) * sigma_x_scale))
        sc = dataclasses.replace(sc, estimator=dataclasses.replace(sc.estimator, settings=parts))
    data = [generate(sc, np.random.default_rng(s)) for s in np.random.SeedSequence(seed).spawn(runs)]
    out: dict = {}
    for name in filters:
        fseeds = np.random.SeedSequence(filter_seed).spawn(runs)
        errs = []
        for run, fs in zip(data, fseeds, strict=True):
            f = build_filter(name, sc.estimator, np.random.default_rng(fs))
            est = np.array([f.step(run.t[k], run.y[k], run.mask[k], run.u[k]).fault_estimate
                            for k in range(run.t.size)])
            errs.append(est - run.faults)
        rmse = np.sqrt(np.mean(np.square(errs), axis=0))            # (K, nf)
        out[name] = {}
        for j, fc in enumerate(sc.faults):
            scale = 1.0 / fc.unit_scale
            row = {f"{t:.2f}": float(rmse[int(round(t / sc.dt_s)) - 1, j] * scale) for t in INSTANTS}
            row["mean"] = float(rmse[:, j].mean() * scale)
            out[name][f"f_{fc.id}"] = row
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario")
    ap.add_argument("filters", help="comma-separated, e.g. RJMRPF,JMRPF")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--sigma-x-scale", type=float, default=1.0)
    args = ap.parse_args(argv)
    res = open_loop_rmse(args.scenario, args.filters.split(","), args.runs, args.sigma_x_scale)
    tables = thesis_tables()
    keys = [f"{t:.2f}" for t in INSTANTS] + ["mean"]
    print(f"{'filter':8s} {'fault':8s} " + " ".join(f"{k:>7s}" for k in keys) + "   thesis")
    for name, faults in res.items():
        for fid, row in faults.items():
            th = tables.get(args.scenario, {}).get("filters", {}).get(name, {}).get(fid)
            ref = " ".join(f"{th[k]:7.3f}" for k in keys) if th else "-"
            print(f"{name:8s} {fid:8s} " + " ".join(f"{row[k]:7.3f}" for k in keys) + f"   {ref}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
