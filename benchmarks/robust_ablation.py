"""Ablation of the robust monitor (docs/robustness.md): what each of its parts buys.

Writes one estimator file per variant (config/estimators/aerosonde-robust.toml with one part taken
out) and one experiment file per (variant, world) into --out, runs `sim-bridge experiment` on each
(RJMRPF only, --runs faulty flights, seed 0: the same flights for every variant) and prints a
markdown table: false alarms by the service's hysteresis (strict yardstick: a declaration standing
in fault-free time counts), faults declared, delays, isolation and fault RMSE.

    .venv/bin/python benchmarks/robust_ablation.py [--worlds real-turbulence,real-dispersed]
        [--runs 100] [--out results/ablation] [--variants full,no-fold,...]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

from fdir_service.paths import config_dir

ROBUST = "aerosonde-robust"


def _drop_fold(text: str) -> str:
    return re.sub(r'^on_exit = "reset_or_fold".*\n', "", text, flags=re.M)


def _drop_altimeter_fold(text: str) -> str:
    blocks = text.split("[[faults]]")
    keep = [b if not re.search(r'^target = "(gnss_alt|baro_alt)"', b, flags=re.M) else _drop_fold(b)
            for b in blocks[1:]]
    return "[[faults]]".join([blocks[0], *keep])


def _set_part(key: str, value: str):
    def edit(text: str) -> str:
        new, n = re.subn(rf"^{key} = .*$", f"{key} = {value}", text, flags=re.M)
        return new if n else text.replace("[parts]\n", f"[parts]\n{key} = {value}\n", 1)
    return edit


VARIANTS = {
    "full": ("the robust monitor as configured", lambda t: t),
    "no-fold": ("exits never fold a sensor fault into the state (faults.on_exit = \"reset\")", _drop_fold),
    "no-fold-alt": ("the altimeters' exits never fold (their on_exit = \"reset\"); theta and q still do",
                    _drop_altimeter_fold),
    "no-faint": ("a faint mode-1 fault exits at pi10 like any other (parts.pi10_faint = 0)",
                 _set_part("pi10_faint", "0.0")),
    "no-window": ("gyro sentinels from the gyro row only (parts.rate_sentinel = \"row\")",
                  _set_part("rate_sentinel", '"row"')),
    "no-drift": ("no drift / model-error mode: mode-0 entries evolve as in mode 1 and reset to 0 on "
                 "exit (parts.mode0 = \"reset_on_exit\")", _set_part("mode0", '"reset_on_exit"')),
    "no-tail": ("no heavy tail on the pitch rate's process noise (parts.q_tail = [0, 1])",
                _set_part("q_tail", "[0.0, 1.0]")),
}


def write_variant(out: Path, name: str, world: str) -> Path:
    """The experiment file of `world` monitored by variant `name`; returns its path."""
    est_text = (config_dir() / "estimators" / f"{ROBUST}.toml").read_text()
    est = out / "estimators" / f"{name}.toml"
    est.parent.mkdir(parents=True, exist_ok=True)
    est.write_text(VARIANTS[name][1](est_text))
    exp_text = (config_dir() / "experiments" / f"{world}.toml").read_text()
    if f'use = "{ROBUST}"' not in exp_text:
        raise SystemExit(f"{world}: its estimator is not {ROBUST}")
    exp = out / "experiments" / f"{world}-{name}.toml"
    exp.parent.mkdir(parents=True, exist_ok=True)
    exp.write_text(exp_text.replace(f'use = "{ROBUST}"', f'use = "{est.resolve()}"'))
    return exp


def run_variant(exp: Path, folder: Path, runs: int) -> dict:
    """results.json's RJMRPF entry of one variant (run unless already there)."""
    res = folder / "results.json"
    if not res.exists():
        cli = "import sys; from sim_bridge.cli import main; sys.exit(main())"
        subprocess.run([sys.executable, "-c", cli, "experiment", str(exp), "--runs", str(runs),
                        "--out", str(folder), "--filters", "RJMRPF", "--no-figures", "--quiet"], check=True)
    return json.loads(res.read_text())["filters"]["RJMRPF"]


def row(name: str, world: str, r: dict) -> str:
    y, rm = r["yardstick"], r["rmse"]
    d = y["delay_s"]
    def fmt(x: float | None) -> str:
        return "—" if x is None else f"{x:.2f}"
    return (f"| {name} | {world} | {y['false_alarms']} ({y['false_alarms_per_hour']:.2f} / h) | "
            f"{y['detected']} / {y['episodes']} | {fmt(d['median'])} / {fmt(d['p90'])} | "
            f"{fmt(y['isolation_accuracy'])} | {rm['f_theta']['mean']:.3f} / {rm['f_q']['mean']:.3f} / "
            f"{rm['f_de']['mean']:.3f} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default="real-turbulence,real-dispersed")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--out", type=Path, default=Path("results/ablation"))
    ap.add_argument("--variants", default=",".join(VARIANTS))
    args = ap.parse_args(argv)
    names = args.variants.split(",")
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        ap.error(f"unknown variant {unknown[0]!r}; choose from {', '.join(VARIANTS)}")
    lines = ["| variant | world | false alarms in the faulty flights' fault-free time | faults declared | "
             "median / p90 delay (s) | right fault isolated | f_theta / f_q / f_de RMSE (deg, deg/s, deg) |",
             "|---|---|---|---|---|---|---|"]
    for name in names:
        for world in args.worlds.split(","):
            exp = write_variant(args.out, name, world)
            lines.append(row(name, world, run_variant(exp, args.out / name / world, args.runs)))
            print(lines[-1], flush=True)
    print()
    for name in names:
        print(f"- {name}: {VARIANTS[name][0]}")
    print()
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
