"""Campaign reports: results.json (the thesis's table quantities, SPEC section 8), report.md (our
table beside the thesis's, ratio ours/thesis) and PNG figures like the thesis's.

Units in reports follow thesis_tables.json: p_d m, u and w m/s, theta deg, q deg/s, f_<id> in the
fault's unit (m, deg, deg/s). Fault rows are the estimator's monitored faults; their truth is the
world's injected fault of the same id (zero where the world injects none).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fdir_service.paths import config_dir
from sim_bridge.campaign import GATE, Campaign, FilterRuns
from sim_bridge.metrics import (
    TABLE_TIMES,
    detection_metrics,
    fault_episodes,
    median_run,
    rmse_over_runs,
    table_columns,
)
from sim_bridge.scenario import Scenario
from sim_bridge.type_yardstick import GOALS, MISSED, is_typed, scenario_yardsticks
from sim_bridge.yardstick import GRACE_S, ROC_THRESHOLDS, Hysteresis, rate_upper_bound, yardstick

DEG = 180.0 / math.pi
STATE_QUANTITIES = (("p_d", "m", 1.0), ("u", "m/s", 1.0), ("w", "m/s", 1.0), ("theta", "deg", DEG),
                    ("q", "deg/s", DEG))
COLUMNS = tuple(f"{t:.2f}" for t in TABLE_TIMES) + ("mean",)

# The thesis's orderings on mean RMSE (issue 4 acceptance): (scenario, quantity, chain, strict).
ORDERINGS = (
    ("ch4", "f_gnss", ("JMRPF", "IMM-KF"), True),
    ("ch4", "f_baro", ("JMRPF", "IMM-KF"), True),
    ("ch4", "p_d", ("JMRPF", "IMM-KF"), True),
    ("ch5a", "f_theta", ("RJMRPF", "JMRPF", "RPF"), True),
    ("ch5b", "f_theta", ("RJMRPF", "JMRPF", "RPF"), True),
    ("ch5c", "f_de", ("RJMRPF", "RRPF"), False),
    ("ch5c", "f_q", ("RJMRPF", "RRPF"), False),
    ("ch6", "f_theta", ("AJMRPF", "JMRPF"), True),
)
REFERENCE_ORDERINGS = (
    ("ch6", "f_theta", ("AJMRPF-thesis", "JMRPF"), True),
)
"""Shown beside ORDERINGS for reference, not acceptance: ch6's AJMRPF uses the adaptive matrix as
an importance-weighted proposal (estimator.adaptive_transition = "proposal"); AJMRPF-thesis is the
thesis's eq. 6.1 as written (docs/estimation.md, "ch6")."""
REFERENCE_LABEL = " (reference: the thesis's adaptive matrix as written)"

# Where a proposed filter misses the thesis's mean fault RMSE, the investigated reason, keyed
# (scenario, quantity); printed under each miss. Empty: in the 100-run campaigns of 2026-11-22
# every proposed filter meets the thesis's mean (the reasons of the earlier misses, and what
# closed them, are in docs/estimation.md). Add an entry, measured, when a change makes one miss.
EXPLANATIONS_BASIS = ("Reasons measured on closed-loop campaigns (N = 1000) with the filters and scenario "
                      "files of the date given in each; re-check them when those change.")
EXPLANATIONS: dict[tuple[str, str], str] = {}

# Notes on an ordering, keyed (scenario, quantity): printed under the orderings table.
ORDERING_NOTES: dict[tuple[str, str], str] = {
    ("ch6", "f_theta"):
        "ch6: the margin is small. Bootstrap over the 100 runs (paired, 2000 resamples), AJMRPF - "
        "JMRPF mean f_theta RMSE: 95 % interval [-0.0065, -0.0006] deg; AJMRPF-thesis - JMRPF "
        "[+0.0064, +0.0126] deg; a second 100-run campaign (seed 1) gives AJMRPF 0.128 vs JMRPF 0.133. "
        "AJMRPF gains at the step's onset and during it (10-20 s); on the "
        "ramp both follow with the random-walk fault model's lag. The thesis's matrix as written "
        "beats JMRPF when the fixed pi01 gives few sentinels: N = 200, 20 runs, 0.153 vs 0.191; "
        "N = 100, 0.161 vs 0.244 (docs/estimation.md, \"ch6\").",
}

# Where our filters or settings differ from the thesis as written, each measured and documented in
# docs/estimation.md (the thesis's behaviour stays selectable); shown on the combined page.
DEPARTURES: tuple[str, ...] = (
    "sigma_x read as a white-noise density (`sigma_x_basis = \"sqrt_second\"`, ch4/ch5a/ch5b/ch6): "
    "per-step std = sigma_x sqrt(dt). It reproduces the thesis's onset columns; the per-step "
    "reading gives ~3x its pitch error.",
    "Prior-weighted sentinels (`sentinel_weighting = \"prior\"`, ch4/ch5a/ch5c/ch6; ch5c's "
    "elevator too): a sentinel's weight carries p(f | jump) / q(f) with a uniform amplitude prior on "
    "+-amplitude_max. With Alg. 4.1 as written a sentinel always fits its row exactly, so "
    "fault-free P(fault) drifts to 0.3-1.",
    "Per-mode jitter (`jitter = \"per_mode\"`, ch4/ch5a/ch5c/ch6): one kernel per mode pattern, so a "
    "fault-free particle is not jittered along the faulty particles' (state, fault) correlation.",
    "A robust Kalman gain for the R-variants (a numerically singular S is handled, not raised).",
    "Pitch process noise 0.001 rad/sqrt(s) in ch5a/ch5b/ch6 (eq. 5.18/6.73: 0.02): the process model "
    "is the simulator's own airframe, and 0.02 lets the pitch state absorb a growing pitch fault.",
    "ch6: the adaptive matrix as an importance-weighted proposal (`adaptive_transition = "
    "\"proposal\"`): the Pfa-driven pi01 proposes sentinels, weights carry P_model / P_proposal "
    "with the fixed matrix, pi10 stays fixed. The thesis's eq. 6.1 as written runs beside it as "
    "AJMRPF-thesis.",
    "ch5c: actuator sentinels consistent with their amplitude (`actuator_sentinel = "
    "\"consistent\"`): a jump of the elevator fault by dF also moves the airframe state by B_a dF, "
    "since eq. 4.13's amplitude is the fault that acted over the last frame; its sentinels then take "
    "the prior weighting as well.",
)

# Notes that apply to every comparison with the thesis's tables (shown under each goal table).
READING_NOTES: tuple[str, ...] = (
    "Frame alignment: the thesis's columns at 20.05 s (and 40.05 s in ch5b) show the whole fault "
    "amplitude just after the fault ended (49.9 deg in Table 5.2) while at 10.05 s the fault is "
    "already detected: its estimate at t_k appears to be compared with the truth one frame later "
    "(or its fault windows are (start, end]). Ours compares the estimate at t_k with the truth at "
    "t_k, so our 20.05 s and 40.05 s columns read below the thesis's and our 10.05 s columns above. "
    "This moves single columns, and the means by at most one frame of full-amplitude error / 1000.",
    "Closed loop: every filter's autopilot flies on that filter's own estimate, so each filter has "
    "its own truth; a filter that loses the pitch (in the interim ch5b campaign, JMRPF and RPF in "
    "some runs: theta RMSE 67 deg at 40 s) makes its aircraft fly on a wrong pitch, which feeds "
    "back into its errors.",
)


FLIES_ON = {
    "monitor": "every filter's autopilot flies on that filter's own estimate.",
    "onboard": "the autopilot flies on its own navigation, the filters only watch (navigation "
               "\"onboard\": the true state through its sensors' faults, sim_bridge/onboard_nav.py).",
    "truth": "the autopilot flies on the true state, the filters only watch (navigation \"truth\": a "
             "navigation the faulty sensor does not reach, sim_bridge/onboard_nav.py).",
}
"""What a report says the autopilot flew on, by results.json's "navigation" (absent: "monitor")."""


def reading_notes_for(doc: dict) -> tuple[str, ...]:
    """READING_NOTES for a campaign's results doc: the closed-loop note only when the autopilot flew
    on the filters' estimates (navigation "monitor", or no record of it)."""
    if doc.get("navigation", "monitor") == "monitor":
        return READING_NOTES
    return tuple(n for n in READING_NOTES if not n.startswith("Closed loop:"))


def thesis_tables() -> dict:
    """The thesis's Tables 4.1-6.1 (thesis_tables.json): config/experiments/, else docs/results/."""
    here = Path(__file__).resolve().parent.parent
    name = "thesis_tables.json"
    for p in (config_dir() / "experiments" / name, here / "docs" / "results" / name,
              Path("/work/shared") / name):
        if p.exists():
            return json.loads(p.read_text())
    return {}


def quantities(scenario: Scenario) -> list[tuple[str, str]]:
    """(name, unit) of every table quantity of the scenario, states first, then the estimated faults."""
    faults = [(f"f_{f.id}", f.unit) for f in scenario.estimator.faults]
    return [(q, u) for q, u, _ in STATE_QUANTITIES] + faults


def _series(scenario: Scenario, fr: FilterRuns) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """quantity -> (estimate (R, K), truth (R, K)) in table units."""
    out = {}
    for i, (q, _, scale) in enumerate(STATE_QUANTITIES):
        out[q] = (fr.z_hat[:, :, i] * scale, fr.z_true[:, :, i] * scale)
    for j, f in enumerate(scenario.estimator.faults):
        s = 1.0 / f.unit_scale
        out[f"f_{f.id}"] = (fr.f_hat[:, :, j] * s, fr.f_true[:, :, j] * s)
    return out


def rmse_curves(scenario: Scenario, fr: FilterRuns) -> dict[str, np.ndarray]:
    """quantity -> RMSE_k (K,) in table units."""
    return {q: rmse_over_runs(e, t) for q, (e, t) in _series(scenario, fr).items()}


def filter_median_run(scenario: Scenario, fr: FilterRuns) -> int:
    """SPEC section 8 median run of a filter on its fault errors (on its state errors if it gives no
    fault magnitude, like EKF-GATE)."""
    err = np.abs(fr.f_hat.astype(float) - fr.f_true)
    if not np.isfinite(err).any():
        err = np.abs(fr.z_hat.astype(float) - fr.z_true)
    return median_run(err)


ENVIRONMENT_PACKAGES = ("numpy", "scipy", "jsbsim")
"""The packages whose builds decide a campaign's bits (with the Python version): recorded in results.json."""


def environment() -> dict[str, str]:
    """Python's and ENVIRONMENT_PACKAGES' versions, the machine (`platform.machine`), and what else
    decides the bits on a machine: numpy's SIMD kernels in use (`numpy_simd`, set by
    NPY_DISABLE_CPU_FEATURES), the BLAS library's kernel for this CPU (`blas_core`, threadpoolctl)
    and the code's commit (`commit`, "-dirty" with uncommitted changes; "unknown" outside git).
    The same code and seed fly the same bits on the same builds and kernels; another build or
    kernel may round differently, and a world whose faults upset the aircraft amplifies that into
    other flights."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    def ver(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "absent"

    return {"python": platform.python_version(), **{n: ver(n) for n in ENVIRONMENT_PACKAGES},
            "machine": platform.machine(), "numpy_simd": _numpy_simd(), "blas_core": _blas_core(),
            "commit": _commit()}


def _numpy_simd() -> str:
    """numpy's dispatched SIMD targets this process uses, e.g. "X86_V3" ("" if numpy hides them)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:
        return ""
    return " ".join(t for t in __cpu_dispatch__ if __cpu_features__.get(t))


def _blas_core() -> str:
    """The BLAS libraries' names and CPU kernels, e.g. "openblas 0.3.31 Haswell"."""
    from threadpoolctl import threadpool_info

    return ", ".join(f"{i.get('internal_api', '?')} {i.get('version', '?')} {i.get('architecture', '?')}"
                     for i in threadpool_info() if i.get("user_api") == "blas")


def _commit() -> str:
    """`git describe --always --dirty` of the package's tree, "unknown" where there is none (or
    where this file is not tracked there: an installed copy inside some other repository)."""
    import subprocess
    from pathlib import Path

    here = Path(__file__).resolve()
    try:
        for cmd in (["git", "ls-files", "--error-unmatch", here.name],
                    ["git", "describe", "--always", "--dirty", "--abbrev=12"]):
            out = subprocess.run(cmd, cwd=here.parent, capture_output=True, text=True, timeout=10,
                                 check=True)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() or "unknown"


def _environment_text(env: dict[str, str] | None) -> str:
    """' Flown with Python 3.11.7, numpy 2.4.6, ... (x86_64; numpy SIMD X86_V3, BLAS openblas
    0.3.31 Haswell; code 1a2b3c4d5e6f).' ('' without a record; older records lack the last three)."""
    if not env:
        return ""
    pkgs = ", ".join(f"{n} {env[n]}" for n in ENVIRONMENT_PACKAGES if n in env)
    extra = [f"{label} {env[key]}" for key, label in (("numpy_simd", "numpy SIMD"),
             ("blas_core", "BLAS"), ("commit", "code")) if env.get(key)]
    where = "; ".join([env.get("machine", "?"), *extra])
    return f" Flown with Python {env.get('python', '?')}, {pkgs} ({where})."


def summarise(camp: Campaign) -> dict:
    """The results.json document of a campaign."""
    sc = camp.scenario
    doc = {"scenario": sc.id, "runs": camp.runs, "particles": camp.particles, "seed": camp.seed,
           "navigation": sc.navigation, "wall_s": round(camp.wall_s, 3), "environment": environment(),
           "filters": {}}
    hold = 0.25
    for name, fr in camp.filters.items():
        t = fr.t
        ok = np.ones(fr.z_hat.shape[0], bool)
        ok[[f.run for f in fr.failures]] = False
        rmse = {q: table_columns(c, t) for q, c in rmse_curves(sc, fr).items()}
        active = fr.fault_active(sc)
        det = {f.id: detection_metrics(t, fr.prob[ok, :, j], fr.f_true[ok, :, j], hold_s=hold,
                                       active=active[ok, :, j])
               for j, f in enumerate(sc.estimator.faults)}
        doc["filters"][name] = {
            "rmse": rmse, "detection": det,
            "runtime_s": float(np.nanmean(fr.filter_s)),
            "runtime_total_s": float(np.nansum(fr.filter_s)),
            "step_ms": float(np.nanmean(fr.filter_s) / len(t) * 1e3),
            "median_run": filter_median_run(sc, fr),
            "failed_runs": [{"run": f.run, "sim_seed": f.sim_seed, "error": f.error} for f in fr.failures],
            "yardstick": _yardstick(camp, fr),
        }
    return doc


def _yardstick(camp: Campaign, fr: FilterRuns) -> dict | None:
    """The safety yardstick (sim_bridge.yardstick) of one filter's runs."""
    if fr.world_faults is None:
        return None
    return scenario_yardstick(camp.scenario, fr.t, fr.prob, fr.f_hat, fr.world_faults,
                              fr.world_active, fr.sim_seeds)


def scenario_yardstick(sc: Scenario, t: np.ndarray, prob: np.ndarray, f_hat: np.ndarray,
                       world_faults: np.ndarray, world_active: np.ndarray | None, sim_seeds: np.ndarray,
                       rule: Hysteresis | None = None, thresholds: tuple[float, ...] = ROC_THRESHOLDS
                       ) -> dict:
    """results.json's `yardstick` of R runs' traces (prob, f_hat (R, K, nf); world_faults,
    world_active (R, K, nw); sim_seeds (R,)) under rule (default: the service's hysteresis), with
    the ROC over thresholds; "by_type" too for a typed world or estimator."""
    ids, wids = [f.id for f in sc.estimator.faults], [f.id for f in sc.faults]
    if not (is_typed(sc.faults) or is_typed(sc.estimator.faults)):   # bias only: matched by id
        return yardstick(t, prob, ids, world_faults, wids, rule=rule, thresholds=thresholds,
                         world_active=world_active)
    # a typed world, or a typed estimator (its fault-free worlds too): by item, as the service declares
    strict, by_type = scenario_yardsticks(sc, t, prob, f_hat, world_faults, sim_seeds, rule)
    items = yardstick(t, strict.pop("prob"), strict.pop("fault_ids"), world_faults, wids, rule=rule,
                      thresholds=thresholds, **strict)
    return {**items, "by_type": by_type}


def check_orderings(results: dict[str, dict], orderings: tuple = ORDERINGS) -> list[dict]:
    """The thesis's orderings on mean RMSE, for the scenarios present. results: id -> results.json;
    orderings: ORDERINGS (acceptance) or REFERENCE_ORDERINGS."""
    rows = []
    for sid, q, chain, strict in orderings:
        if sid not in results:
            continue
        fl = results[sid]["filters"]
        if orderings is not ORDERINGS and not all(n in fl for n in chain):
            continue
        vals = [fl.get(n, {}).get("rmse", {}).get(q, {}).get("mean") for n in chain]
        ok = all(v is not None for v in vals) and all(
            (a < b) if strict else (a <= b) for a, b in zip(vals, vals[1:], strict=False))
        rows.append({"scenario": sid, "quantity": q, "chain": chain, "values": vals, "strict": strict,
                     "holds": bool(ok)})
    return rows


def _ordering_notes(orders: list[dict]) -> list[str]:
    """ORDERING_NOTES of the orderings shown, as markdown lines (each followed by a blank line)."""
    keys = dict.fromkeys((o["scenario"], o["quantity"]) for o in orders)
    return [line for k in keys if k in ORDERING_NOTES for line in (ORDERING_NOTES[k], "")]


def goal_rows(scenario: Scenario, doc: dict, thesis: dict) -> list[dict]:
    """The proposed filter's mean fault RMSE against the thesis's (goal: at or below)."""
    prop = scenario.proposed
    if scenario.id not in thesis:          # not a thesis experiment: no table to meet
        return []
    th = thesis.get(scenario.id, {}).get("filters", {}).get(prop, {})
    rows = []
    for f in scenario.estimator.faults:
        q = f"f_{f.id}"
        ours = doc["filters"].get(prop, {}).get("rmse", {}).get(q, {}).get("mean")
        ref = th.get(q, {}).get("mean")
        ratio = ours / ref if ours is not None and ref else None
        rows.append({"filter": prop, "quantity": q, "ours": ours, "thesis": ref, "ratio": ratio,
                     "met": ours is not None and ref is not None and ours <= ref})
    return rows


# ----------------------------------------------------------------------------- markdown

def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 100:
        return f"{v:.1f}"
    if a >= 0.01:
        return f"{v:.{digits}f}"
    return f"{v:.2e}"


def markdown(  # noqa: C901 - report assembly: one section after another, each a few lines
        scenario: Scenario, doc: dict, thesis: dict, figures: list[str], wall_s: float | None = None,
        fig_prefix: str = "", reading_notes: bool = True, explain: bool = True) -> str:
    """report.md for one scenario. reading_notes: the READING_NOTES under the goal table; explain:
    each miss's EXPLANATIONS entry (combined_markdown gives them once, at the top)."""
    sid = scenario.id
    th_all = thesis.get(sid, {}).get("filters", {})
    where = (f"Thesis section {scenario.thesis_section}, Table {scenario.thesis_table}. "
             if scenario.thesis_table else "")
    L = [f"# {sid}: {scenario.title}", "",
         where + f"{doc['runs']} closed-loop Monte Carlo runs, N = {doc['particles']} particles, seed "
         f"{doc['seed']}; {FLIES_ON[doc.get('navigation', 'monitor')]}"
         + (f" Campaign wall time {wall_s:.1f} s." if wall_s is not None else "")
         + _environment_text(doc.get("environment")), ""]
    orders = check_orderings({sid: doc})
    refs = check_orderings({sid: doc}, REFERENCE_ORDERINGS)
    if orders:
        L += ["## The thesis's orderings (mean RMSE)", "", "| quantity | ordering | ours | holds |",
              "|---|---|---|---|"]
        for o in orders + refs:
            rel = " < " if o["strict"] else " <= "
            label = REFERENCE_LABEL if o in refs else ""
            L.append(f"| {o['quantity']} | {rel.join(o['chain'])}{label} | "
                     f"{' / '.join(_fmt(v) for v in o['values'])} | {_fmt(o['holds'])} |")
        L.append("")
        L += _ordering_notes(orders)
    L += yardstick_markdown(doc)
    goals = goal_rows(scenario, doc, thesis)
    if goals:
        L += [f"## Goal: {scenario.proposed} mean fault RMSE at or below the thesis's", "",
              "| quantity | ours | thesis | ours/thesis | met |", "|---|---|---|---|---|"]
        for g in goals:
            L.append(f"| {g['quantity']} | {_fmt(g['ours'])} | {_fmt(g['thesis'])} | "
                     f"{_fmt(g['ratio'], 2)} | {_fmt(g['met'])} |")
        L.append("")
        misses = [g for g in goals if not g["met"]]
        for g in misses:
            why = EXPLANATIONS.get((sid, g["quantity"]))
            pct = (g["ratio"] - 1) * 100 if g["ratio"] is not None else None
            L.append(f"- **Miss on {g['quantity']}**: {_fmt(g['ours'])} vs {_fmt(g['thesis'])} "
                     f"({'+' + format(pct, '.0f') + ' %' if pct is not None else 'no value'}). "
                     + ((why if why else "Reason: not investigated yet.") if explain
                        else "Why: see 'Where we miss, and why' at the top."))
        if misses:
            L += ["", EXPLANATIONS_BASIS, ""] if explain else [""]
        if reading_notes:
            L += ["Reading the tables:", ""] + [f"- {n}" for n in reading_notes_for(doc)] + [""]
    for name, fd in doc["filters"].items():
        th = th_all.get(name, th_all.get(name.removesuffix("-thesis"), {}))
        L += [f"## {name}", "", "RMSE, ours | thesis (ratio ours/thesis on the mean)", "",
              "| quantity | unit | " + " | ".join(f"{c} s" for c in COLUMNS[:-1])
              + " | mean | thesis mean | ratio |",
              "|---|---|" + "---|" * (len(COLUMNS) + 2)]
        for q, unit in quantities(scenario):
            ours = fd["rmse"].get(q, {})
            ref = th.get(q, {})
            cells = []
            for c in COLUMNS[:-1]:
                cells.append(f"{_fmt(ours.get(c))} \\| {_fmt(ref.get(c))}" if ref else _fmt(ours.get(c)))
            m, rm = ours.get("mean"), ref.get("mean")
            ratio = m / rm if (m is not None and rm) else None
            L.append(f"| {q} | {unit} | " + " | ".join(cells) + f" | {_fmt(m)} | {_fmt(rm)} | "
                     f"{_fmt(ratio, 2)} |")
        L.append("")
        L += ["| fault | detection delay (s) | episodes detected | false-alarm time fraction | "
              "missed-detection time fraction |", "|---|---|---|---|---|"]
        for fid, d in fd["detection"].items():
            L.append(f"| {fid} | {_fmt(d['delay_s'])} | {_fmt(d['detected_fraction'], 2)} | "
                     f"{_fmt(d['false_alarm_fraction'])} | {_fmt(d['missed_fraction'])} |")
        L += ["", f"Filter time per run {fd['runtime_s']:.2f} s ({fd['step_ms']:.3f} ms per step); "
              f"median run {fd['median_run']}.", ""]
        if fd.get("failed_runs"):
            L += [f"**{len(fd['failed_runs'])} run(s) failed** and are left out of the figures above: "
                  + "; ".join(f"run {f['run']}: {f['error']}" for f in fd["failed_runs"][:5]), ""]
    if GATE in doc["filters"]:
        L += [f"{GATE} gives no fault magnitude (its fault estimate is NaN, shown —); its P(fault) is "
              "1 on a declared channel, else 0.", ""]
    if figures:
        L += ["## Figures", ""]
        for f in figures:
            L += [f"![{f}]({fig_prefix}{f})", ""]
    return "\n".join(L)


# ----------------------------------------------------------------------------- figures

def _colors(names):
    import matplotlib.pyplot as plt
    cyc = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    return {n: cyc[i % len(cyc)] for i, n in enumerate(names)}


def _log_floor(ax, decades: float = 3.5) -> None:
    """Keep a log axis readable: at most `decades` below its largest value (a single near-zero
    RMSE_k, e.g. the frame a fault ends, would otherwise squash every curve into the top)."""
    ys = [ln.get_ydata() for ln in ax.get_lines()]
    vals = np.concatenate([np.asarray(y, float).ravel() for y in ys]) if ys else np.array([])
    vals = vals[np.isfinite(vals) & (vals > 0)]
    if vals.size:
        top = float(np.max(vals))
        ax.set_ylim(bottom=max(float(np.min(vals)), top * 10.0 ** -decades) / 1.5, top=top * 1.5)


def figures(  # noqa: C901 - figure assembly: one figure after another, each a few lines
        camp: Campaign, doc: dict, out: Path, prefix: str = "") -> list[str]:
    """Write the PNG figures of a campaign into `out`; return their file names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sc = camp.scenario
    names = list(camp.filters)
    col = _colors(names)
    files: list[str] = []
    nf = len(sc.estimator.faults)

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(out / f"{prefix}{name}", dpi=110, bbox_inches="tight")
        plt.close(fig)
        files.append(f"{prefix}{name}")

    t_ref = camp.filters[names[0]].t
    windows = {}
    active_ref = camp.filters[names[0]].fault_active(sc)
    for j in range(nf):     # the episodes of estimated fault j in the world's injected faults
        active = np.any(active_ref[:, :, j], axis=0)
        windows[j] = [(t_ref[a], t_ref[b - 1]) for a, b in fault_episodes(active)]

    def shade(ax, j):
        for a, b in windows[j]:
            ax.axvspan(a, b, color="0.85", alpha=0.5, lw=0, zorder=0)

    # 1. median-run fault estimates vs truth, and P(fault), per filter (fault windows shaded)
    fig, axes = plt.subplots(2, nf, figsize=(7 * nf, 7), squeeze=False, sharex=True,
                             gridspec_kw={"height_ratios": [3, 2]})
    for j, f in enumerate(sc.estimator.faults):
        s = 1.0 / f.unit_scale
        ax, axp = axes[0, j], axes[1, j]
        shade(ax, j)
        shade(axp, j)
        first = True
        for n in names:
            fr = camp.filters[n]
            r = doc["filters"][n]["median_run"]
            if first:
                ax.plot(fr.t, fr.f_true[r, :, j] * s, "k-", lw=2.5, alpha=0.35, label="truth")
                first = False
            if np.isfinite(fr.f_hat[r, :, j]).any():
                ax.plot(fr.t, fr.f_hat[r, :, j] * s, color=col[n], lw=1, label=f"{n} (run {r})")
            gate = not np.isfinite(fr.f_hat[r, :, j]).any()
            axp.plot(fr.t, fr.prob[r, :, j], color=col[n], lw=1.4 if gate else 1,
                     ls="--" if gate else "-",
                     label=f"{n} (run {r}, declared 0/1)" if gate else f"{n} (run {r})")
        ax.set_ylabel(f"f_{f.id} ({f.unit})")
        ax.set_title(f"{sc.id}: median-run estimate of f_{f.id} (grey: fault active)")
        ax.legend(fontsize=8, loc="upper left")
        axp.axhline(0.5, color="0.5", lw=0.8, ls=":")
        axp.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
        axp.set_ylabel(f"P(f_{f.id})")
        axp.set_xlabel("t (s)")
        axp.set_ylim(-0.05, 1.05)
    save(fig, "fault_estimates_median.png")

    # 2. RMSE vs time, faults and states
    curves = {n: rmse_curves(sc, camp.filters[n]) for n in names}
    fig, axes = plt.subplots(nf, 1, figsize=(10, 3.6 * nf), squeeze=False, sharex=True)
    for j, f in enumerate(sc.estimator.faults):
        ax = axes[j, 0]
        shade(ax, j)
        for n in names:
            c = curves[n][f"f_{f.id}"]
            if np.isfinite(c).any():
                ax.semilogy(camp.filters[n].t, c, color=col[n], lw=1, label=n)
        ax.set_title(f"{sc.id}: RMSE of f_{f.id} ({f.unit}), {camp.runs} runs"
                     + (f" ({GATE}: no magnitude)" if GATE in names else ""))
        ax.set_ylabel(f"RMSE ({f.unit})")
        _log_floor(ax)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    axes[-1, 0].set_xlabel("t (s)")
    save(fig, "rmse_faults.png")
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5), sharex=True)
    flat = axes.ravel()
    for i, (q, unit, _) in enumerate(STATE_QUANTITIES):
        for j in range(nf):
            shade(flat[i], j)
        for n in names:
            flat[i].semilogy(camp.filters[n].t, curves[n][q], color=col[n], lw=1, label=n)
        flat[i].set_title(f"{sc.id}: RMSE of {q} ({unit}), {camp.runs} runs")
        _log_floor(flat[i])
        flat[i].grid(True, which="major", alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("t (s)")
    handles, labels = flat[0].get_legend_handles_labels()
    flat[5].axis("off")
    flat[5].legend(handles, labels, loc="center", fontsize=10, title="filter (grey: a fault active)")
    save(fig, "rmse_states.png")

    # 3. the 20 most weighted particles every second, proposed filter's median run (Fig. 4.13)
    prop = sc.proposed
    if prop in camp.filters:
        fr = camp.filters[prop]
        r = doc["filters"][prop]["median_run"]
        fig, axes = plt.subplots(nf, 1, figsize=(9, 3.2 * nf), squeeze=False, sharex=True)
        for j, f in enumerate(sc.estimator.faults):
            s = 1.0 / f.unit_scale
            ax = axes[j, 0]
            ax.plot(fr.t, fr.f_true[r, :, j] * s, "k-", lw=1, alpha=0.6, label="truth")
            x = fr.top_x[r, :, :, 5 + j] * s
            w = fr.top_w[r]
            tt = np.repeat(fr.top_t[:, None], x.shape[1], axis=1)
            sc_ = ax.scatter(tt.ravel(), x.ravel(), c=w.ravel(), s=10, cmap="viridis")
            ax.set_ylabel(f"f_{f.id} ({f.unit})")
            ax.set_title(f"{sc.id} {prop}: 20 most weighted particles each second (run {r})")
            fig.colorbar(sc_, ax=ax, label="weight")
        axes[-1, 0].set_xlabel("t (s)")
        save(fig, "top_particles.png")

    # 4. adaptive filters: Pfa, Pmd and transition probabilities (Fig. 6.6-6.7), median run
    adaptive = [n for n in names if camp.filters[n].pfa is not None]
    if adaptive:
        fig, axes = plt.subplots(2, nf, figsize=(7 * nf, 6), squeeze=False, sharex=True)
        for n in adaptive:
            fr = camp.filters[n]
            r = doc["filters"][n]["median_run"]
            for j, f in enumerate(sc.estimator.faults):
                axes[0, j].plot(fr.t, fr.pfa[r, :, j], color=col[n], lw=1, label=f"{n} Pfa")
                axes[0, j].plot(fr.t, fr.pmd[r, :, j], color=col[n], lw=1, ls="--", label=f"{n} Pmd")
                axes[0, j].set_title(f"{sc.id}: Pfa, Pmd of f_{f.id} (median run)")
                if fr.transition is not None:
                    tr = fr.transition[r, :, j]
                    axes[1, j].plot(fr.t, tr[:, 0, 1], color=col[n], lw=1, label=f"{n} pi01")
                    axes[1, j].plot(fr.t, tr[:, 1, 0], color=col[n], lw=1, ls="--", label=f"{n} pi10")
                    axes[1, j].set_title(f"transition probabilities of f_{f.id}")
        for ax in axes.ravel():
            ax.legend(fontsize=8)
            ax.set_xlabel("t (s)")
        save(fig, "pfa_pmd_transition.png")
    return files


def write_report(camp: Campaign, out: str | Path, thesis: dict | None = None,
                 make_figures: bool = True) -> dict:
    """Write results.json, report.md and the figures of a campaign into `out`; return results."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    thesis = thesis_tables() if thesis is None else thesis
    doc = summarise(camp)
    (out / "results.json").write_text(json.dumps(doc, indent=1))
    figs = figures(camp, doc, out) + roc_figure(doc, out) if make_figures else []
    (out / "report.md").write_text(markdown(camp.scenario, doc, thesis, figs, camp.wall_s))
    return doc


def _status(docs: dict[str, dict]) -> list[str]:
    """How the campaigns of a combined page were run (runs, N, seed, wall time per scenario)."""
    if not docs:
        return ["No campaign results found."]
    from sim_bridge.scenario import SCENARIO_IDS

    full = min(d["runs"] for d in docs.values()) >= 100 and set(SCENARIO_IDS) <= set(docs)
    L = [("**Status: complete** (every thesis scenario, at least 100 runs)." if full else
          "**Status: interim** (a scenario missing or with fewer than 100 runs; the commit-ready "
          "page comes from `sim-bridge experiment all --runs 100 --out results --publish docs`)."), "",
         "| scenario | runs | particles | seed | wall time (s) |", "|---|---|---|---|---|"]
    for sid, d in docs.items():
        L.append(f"| {sid} | {d['runs']} | {d['particles']} | {d['seed']} | "
                 f"{_fmt(d.get('wall_s'), 1)} |")
    return L + [""]


def combined_markdown(  # noqa: C901 - report assembly, as `markdown`
        root: str | Path, scenario_ids: list[str] | tuple[str, ...], fig_root: str = "",
        thesis: dict | None = None, preamble: str = "") -> str:
    """One document for several campaigns: how they were run, the orderings and goals of all
    scenarios, where and why we miss, then each scenario's report. Reads root/<id>/results.json and
    the PNGs beside it; figures are linked as fig_root + <id>/<file> (e.g. "results/" for
    docs/results.md with figures in docs/results/<id>/).
    """
    root = Path(root)
    thesis = thesis_tables() if thesis is None else thesis
    from sim_bridge.scenario import load_scenario

    docs, scs = {}, {}
    for sid in scenario_ids:
        p = root / sid / "results.json"
        if p.exists():
            docs[sid] = json.loads(p.read_text())
            scs[sid] = load_scenario(sid)
    L = ["# Thesis campaigns: results", ""]
    if preamble:
        L += [preamble, ""]
    L += _status(docs)
    L += ["## The thesis's orderings (mean RMSE)", "",
          "| scenario | quantity | ordering | ours | holds |", "|---|---|---|---|---|"]
    refs = check_orderings(docs, REFERENCE_ORDERINGS)
    for o in check_orderings(docs) + refs:
        rel = " < " if o["strict"] else " <= "
        label = REFERENCE_LABEL if o in refs else ""
        L.append(f"| {o['scenario']} | {o['quantity']} | {rel.join(o['chain'])}{label} | "
                 f"{' / '.join(_fmt(v) for v in o['values'])} | {_fmt(o['holds'])} |")
    L += [""] + _ordering_notes(check_orderings(docs))
    L += ["", "## Goal: each proposed filter's mean fault RMSE at or below the thesis's", "",
          "| scenario | filter | quantity | ours | thesis | ours/thesis | met |",
          "|---|---|---|---|---|---|---|"]
    misses = []
    for sid, doc in docs.items():
        for g in goal_rows(scs[sid], doc, thesis):
            L.append(f"| {sid} | {g['filter']} | {g['quantity']} | {_fmt(g['ours'])} | "
                     f"{_fmt(g['thesis'])} | {_fmt(g['ratio'], 2)} | {_fmt(g['met'])} |")
            if not g["met"]:
                misses.append((sid, g))
    L.append("")
    if misses:
        L += ["## Where we miss, and why", "", EXPLANATIONS_BASIS, ""]
        for sid, g in misses:
            pct = (g["ratio"] - 1) * 100 if g["ratio"] is not None else None
            why = EXPLANATIONS.get((sid, g["quantity"]), "Reason: not investigated yet.")
            by = f"+{pct:.0f} %" if pct is not None else "no value"
            L.append(f"- **{sid} {g['filter']} {g['quantity']}**: {_fmt(g['ours'])} vs "
                     f"{_fmt(g['thesis'])} ({by}). {why}")
        L.append("")
    L += ["## Where we depart from the thesis", "",
          "Each departure is measured against the thesis's version in docs/estimation.md and is a "
          "scenario setting; the thesis's behaviour stays selectable.", ""]
    L += [f"- {d}" for d in DEPARTURES] + [""]
    L += ["## Reading the tables", ""] + [f"- {n}" for n in READING_NOTES] + [""]
    for sid, doc in docs.items():
        figs = sorted(p.name for p in (root / sid).glob("*.png"))
        md = markdown(scs[sid], doc, thesis, figs, doc.get("wall_s"), fig_prefix=f"{fig_root}{sid}/",
                      reading_notes=False, explain=False)
        L += [md.replace("\n# ", "\n## ").replace("\n## ", "\n### ").replace(f"# {sid}:", f"## {sid}:", 1),
              ""]
    return "\n".join(L)


def publish(results_root: str | Path, docs_dir: str | Path,
            scenario_ids: list[str] | tuple[str, ...] | None = None) -> Path:
    """Publish campaign results into the docs: copy results_root/<id>/ (results.json, PNGs) to
    docs_dir/results/<id>/ for every scenario found, write its report.md anew from results.json
    (with this module's current texts), then regenerate docs_dir/results.md
    from everything published under docs_dir/results/ (so publishing one scenario keeps the
    others). Returns the path of results.md."""
    import shutil

    from sim_bridge.scenario import SCENARIO_IDS, load_scenario

    src, docs_dir = Path(results_root), Path(docs_dir)
    ids = list(scenario_ids) if scenario_ids is not None else list(SCENARIO_IDS)
    dest_root = docs_dir / "results"
    thesis = thesis_tables()
    for sid in ids:
        s = src / sid
        if not (s / "results.json").exists():
            continue
        d = dest_root / sid
        if not (d.exists() and d.resolve() == s.resolve()):
            d.mkdir(parents=True, exist_ok=True)
            for old in d.glob("*.png"):
                old.unlink()
            for f in [s / "results.json", *sorted(s.glob("*.png"))]:
                shutil.copy2(f, d / f.name)
        # report.md is rewritten from results.json, so the texts of this module (notes, reasons,
        # departures) stay current without re-running the campaign
        doc = json.loads((d / "results.json").read_text())
        figs = sorted(p.name for p in d.glob("*.png"))
        (d / "report.md").write_text(markdown(load_scenario(sid), doc, thesis, figs, doc.get("wall_s")))
    page = docs_dir / "results.md"
    docs_dir.mkdir(parents=True, exist_ok=True)
    page.write_text(combined_markdown(dest_root, list(SCENARIO_IDS), fig_root="results/"))
    return page


def main(argv: list[str] | None = None) -> int:
    """`python -m sim_bridge.report publish RESULTS [DOCS]`: publish finished campaigns without
    re-running them (RESULTS/<id>/ -> DOCS/results/<id>/, DOCS/results.md regenerated)."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m sim_bridge.report")
    sub = ap.add_subparsers(dest="cmd", required=True)
    pp = sub.add_parser("publish",
                        help="copy RESULTS/<id>/ to DOCS/results/<id>/, regenerate DOCS/results.md")
    pp.add_argument("results", help="campaign output root holding <id>/results.json (e.g. results)")
    pp.add_argument("docs", nargs="?", default="docs", help="docs folder (default docs)")
    pp.add_argument("--scenarios", default=None, help="comma-separated ids (default: all found)")
    args = ap.parse_args(argv)
    ids = args.scenarios.split(",") if args.scenarios else None
    page = publish(args.results, args.docs, ids)
    print(f"published {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def yardstick_markdown(doc: dict) -> list[str]:
    """The safety yardstick of every filter (false alarms per flight hour, detection, delay,
    isolation) and each filter's isolation confusion table, as markdown lines."""
    rows = [(n, fd["yardstick"]) for n, fd in doc["filters"].items() if fd.get("yardstick")]
    if not rows:
        return []
    y0 = rows[0][1]
    L = ["## Safety yardstick", "",
         f"By the service's own declare / clear hysteresis (declare at P >= {y0['p_declare']}); a false "
         "alarm is a stretch of fault-free flight time (no injected fault, none ended within "
         f"{GRACE_S:g} s) with a fault declared, whether the declaration started there or still "
         "stands from an injected fault's time; definitions in sim_bridge/yardstick.py.", "",
         "| filter | false alarms / flight hour | 95 % upper bound | false alarms | fault-free hours | "
         "time falsely declared | faults declared | median delay (s) | p90 delay (s) | "
         "right fault isolated |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    for name, y in rows:
        bound = rate_upper_bound(y["false_alarms"], y["fault_free_hours"])
        L.append(f"| {name} | {_fmt(y['false_alarms_per_hour'], 2)} | {_fmt(bound, 2)} | "
                 f"{y['false_alarms']}{_runs_with(y)} | {_fmt(y['fault_free_hours'], 2)} | "
                 f"{_fmt(y.get('falsely_declared_fraction'))} | {y['detected']} / {y['episodes']}"
                 f"{while_active(y)} | "
                 f"{_fmt(y['delay_s']['median'], 2)} | {_fmt(y['delay_s']['p90'], 2)} | "
                 f"{_fmt(y['isolation_accuracy'], 2)} |")
    L.append("")
    for name, y in rows:
        L += false_alarm_markdown(name, y, doc)
    for name, y in rows:
        L += _confusion_markdown(f"Isolation, {name} (rows: injected; columns: first fault declared)",
                                 "injected", y["isolation"], "none")
    return L + by_type_markdown(rows)


def _runs_with(y: dict) -> str:
    """" (in k of R runs)" for a yardstick with false alarms and its run counts, else "": false
    alarms cluster in runs (a state that departs raises several), so their count alone overstates
    how many flights cried wolf, and a count's change of a few between two builds is within noise."""
    k, runs = y.get("runs_with_false_alarms"), y.get("runs")
    return f" (in {k} of {runs} runs)" if y.get("false_alarms") and k is not None and runs else ""


FALSE_ALARMS_LISTED = 30
"""At most this many false alarms are listed per filter in report.md (results.json has them all)."""


def false_alarm_markdown(name: str, y: dict, doc: dict) -> list[str]:
    """Which runs raised a filter's false alarms (yardstick "false_alarm_list"): run, item, when it
    was declared and how long it stood, with the command that flies one of them again."""
    fas = y.get("false_alarm_list") or []
    if not fas:
        return []
    shown = "; ".join(f"run {fa['run']}: {fa['item']} at {fa['t_s']:.1f} s ({fa['s']:.1f} s)"
                      for fa in fas[:FALSE_ALARMS_LISTED])
    extra = len(fas) - FALSE_ALARMS_LISTED
    more = f"; and {extra} more (results.json)" if extra > 0 else ""
    return [f"False alarms, {name} (run: item declared at, standing for): {shown}{more}. "
            f"To fly run R again and list its declarations: `python benchmarks/false_alarm_runs.py "
            f"{doc.get('scenario', 'WORLD')} --seed {doc.get('seed', 0)}{_navigation_flag(doc)} "
            "--first R --runs R+1`.", ""]


def _navigation_flag(doc: dict) -> str:
    """The flag that flies a campaign's runs again on its autopilot's navigation ("" for a results
    doc written before it was recorded: those all flew on the monitor, the worlds' default)."""
    nav = doc.get("navigation")
    return "" if nav is None else f" --navigation {nav}"


def _confusion_markdown(title: str, head: str, confusion: dict[str, dict[str, int]],
                        none: str) -> list[str]:
    """A confusion table: rows the injected faults, columns what was declared first (`none`: the
    column of nothing declared, last)."""
    if not any(confusion.values()):
        return []
    cols = sorted({c for row in confusion.values() for c in row} - {none}) + [none]
    L = [title, "", f"| {head} | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for wid, row in confusion.items():
        L.append(f"| {wid} | " + " | ".join(str(row.get(c, 0)) for c in cols) + " |")
    return L + [""]


def _goal(v: float | None, goal: float, at_least: bool, unit: str = "") -> str:
    """A figure (2 digits, then unit) with whether it meets its goal (at least / at most `goal`)."""
    if v is None:
        return _fmt(v)
    return f"{_fmt(v, 2)}{unit} ({'met' if (v >= goal if at_least else v <= goal) else 'missed'})"


def while_active(y: dict) -> str:
    """" (D while active)": how many of the detected episodes of a yardstick (or a type's row) y
    were declared before they ended (`yardstick.py`), "" for results written before the figure."""
    during = y.get("detected_during")
    return "" if during is None else f" ({during} while active)"


def _goal_cells(r: dict, delay_unit: str = "") -> tuple[str, str, str]:
    """A type row's detection fraction, median delay and right item-and-type fraction, each with
    whether it meets the issue's goal (`GOALS`)."""
    return (_goal(r["detection_fraction"], GOALS["detection_fraction"], True),
            _goal(r["delay_s"]["median"], GOALS["delay_median_s"], False, delay_unit),
            _goal(r["right_fraction"], GOALS["right_fraction"], True))


def _type_line(name: str, ty: str, r: dict) -> str:
    """One row of the per-fault-type table."""
    mag = ", ".join(f"{_fmt(v)} {u}" for u, v in r["magnitude_rmse"].items()) or _fmt(None)
    det, delay, right = _goal_cells(r)
    det += while_active(r)
    named = r.get("named_s", {})
    past = r.get("delay_3sigma_s", {})
    return (f"| {name} | {ty} | {r['episodes']} | {det} | {delay} | {_fmt(r['delay_s']['p90'], 2)} | "
            f"{_fmt(past.get('median'), 2)} | {right} | {r.get('named', '-')} | "
            f"{_fmt(named.get('median'), 2)} | "
            f"{_fmt(r.get('right_probable_fraction'), 2)} | {_fmt(r.get('right_settled_fraction'), 2)} | "
            f"{_fmt(r['right_item_fraction'], 2)} | {mag} |")


def yardstick_lines(y: dict | None) -> list[str]:
    """What `sim-bridge experiment` prints of a filter's safety yardstick y: false alarms per
    fault-free hour with the rate's 95 % upper bound, and the faults declared; [] without one."""
    if not y:
        return []
    bound = rate_upper_bound(y["false_alarms"], y["fault_free_hours"])
    line = (f"false alarms {y['false_alarms']} in {y['fault_free_hours']:.2f} fault-free h: "
            f"{_fmt(y['false_alarms_per_hour'], 2)} per hour (95 % upper bound {_fmt(bound, 2)})")
    if y["episodes"]:
        line += (f"; faults declared {y['detected']} / {y['episodes']}{while_active(y)}, "
                 f"median delay {_fmt(y['delay_s']['median'], 2)} s")
    return [line]


def _past_3sigma(r: dict) -> str:
    """" (past 3 sigma X s)" where the median delay past 3 sigma differs from the one from the onset."""
    past = r.get("delay_3sigma_s", {}).get("median")
    return f" (past 3 sigma {_fmt(past, 2)} s)" if past is not None and past != r["delay_s"]["median"] else ""


def by_type_lines(y: dict | None) -> list[str]:
    """What `sim-bridge experiment` prints per world fault type of a typed world's yardstick y
    (one line each, the goals beside the figures); [] for a bias-only world."""
    if not y or not y.get("by_type"):
        return []
    return [f"{ty}: detected {det} of {r['episodes']}{while_active(r)}, median delay {delay}"
            f"{_past_3sigma(r)}, right item and type {right}"
            for ty, r in y["by_type"]["types"].items() for det, delay, right in (_goal_cells(r, " s"),)]


def by_type_markdown(rows: list[tuple[str, dict]]) -> list[str]:
    """The per-fault-type table and each filter's (item, type) confusion table, for a world with
    typed faults (yardstick "by_type"), the issue's goals beside the figures; [] for a bias-only
    world. rows: (filter, its yardstick)."""
    typed = [(n, y) for n, y in rows if y.get("by_type")]
    if not typed:
        return []
    L = ["## Per fault type", "",
         "Each injected episode matched to the monitored entries by item and type (definitions in "
         "sim_bridge/type_yardstick.py): detected when its item is declared (P(item) over its types, "
         "the service's hysteresis); right when the first item declared is its own and the type the "
         "service names for it is right (a type is named once it holds >= p_type of P(item), at the "
         "declaration or later: `[publish.declare]`); named: the declarations that named a type before "
         "they cleared, and the median time from the declaration to the name; beside them, the most "
         "probable type at the declaration and 2 s later; the delay past 3 sigma counts from the frame "
         "where the fault first stood 3 noise sigmas of its sensor out (a ramp, a blockage or a stuck "
         "reading starts at 0; the goal is judged on the delay from the onset); magnitude RMSE of the "
         "right entry's estimate "
         "over the active frames, in the fault's unit (- : unitless k - 1, g - 1). False alarms per "
         "flight hour with every type enabled (goal <= "
         f"{GOALS['false_alarms_per_hour']:g}): "
         + ", ".join(f"{n} {_goal(y['false_alarms_per_hour'], GOALS['false_alarms_per_hour'], False)}"
                     for n, y in typed) + ".", "",
         f"| filter | type | episodes | detected (goal >= {GOALS['detection_fraction']:.0%}) | "
         f"median delay s (goal <= {GOALS['delay_median_s']:g} s) | p90 delay s | "
         "median delay past 3 sigma s | "
         f"right item and type named (goal >= {GOALS['right_fraction']:.0%}) | named | named after s | "
         "most probable right at declaration | 2 s later | right item | magnitude RMSE |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    L += [_type_line(n, ty, r) for n, y in typed for ty, r in y["by_type"]["types"].items()]
    L.append("")
    for n, y in typed:
        L += _confusion_markdown(f"Isolation by item and type, {n} (rows: injected item:type; columns: "
                                 "first item declared, with the type named)", "injected",
                                 y["by_type"]["confusion"], MISSED)
    return L


def roc_figure(doc: dict, out: Path, prefix: str = "") -> list[str]:
    """roc.png: false alarms per flight hour against the fraction of injected faults declared, over
    the declare threshold, one curve per filter ([] when there is nothing to draw)."""
    curves = {n: fd["yardstick"]["roc"] for n, fd in doc["filters"].items()
              if fd.get("yardstick") and fd["yardstick"]["episodes"]}
    if not curves:
        return []
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name, roc in curves.items():
        fa = [max(r["false_alarms_per_hour"] or 0.0, 1e-2) for r in roc]
        det = [r["detection_fraction"] or 0.0 for r in roc]
        ax.plot(fa, det, "o-", label=name)
        for r, x, y in zip(roc, fa, det, strict=True):
            ax.annotate(f"{r['p_declare']:g}", (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set(xlabel="false alarms per flight hour (0 drawn at 0.01)",
           ylabel="fraction of injected faults declared", title="Declare-threshold ROC (labels: p_declare)",
           ylim=(-0.02, 1.02))
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / f"{prefix}roc.png", dpi=110)
    plt.close(fig)
    return [f"{prefix}roc.png"]
