"""Figures of a closed-loop run: states, inputs, measurements and faults (Agg backend, SI -> deg)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sim_bridge.scenario import Scenario  # noqa: E402
from sim_bridge.simulate import Trajectory  # noqa: E402

_FAULT_COLOURS = ("tab:red", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive")
_MEAS_STYLE = {"color": "0.55", "lw": 0.6, "alpha": 0.8}


def _shade_faults(ax, traj: Trajectory, scenario: Scenario) -> None:
    """Shade, per fault channel, the time spans where its true value is non-zero."""
    for j in range(len(scenario.faults)):
        on = np.abs(traj.faults[:, j]) > 0.0
        if not on.any():
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            t1 = traj.t[b] if b < traj.t.size else traj.t[-1]
            ax.axvspan(traj.t[a], t1, color=_FAULT_COLOURS[j % len(_FAULT_COLOURS)], alpha=0.10, lw=0)


def plot_run(traj: Trajectory, scenario: Scenario, path: str | Path) -> Path:
    """Write a 4x2 figure of the run to `path` (PNG or anything matplotlib saves); returns the path."""
    names = scenario.sensors.measurements
    col = {n: i for i, n in enumerate(names)}
    t = traj.t
    deg = np.degrees
    fig, axes = plt.subplots(4, 2, figsize=(13, 11), sharex=True)
    ax = axes.ravel()

    # Altitude: truth, GNSS and barometric measurements.
    for n, lab in (("gnss_alt", "GNSS altitude (measured)"), ("baro_alt", "baro altitude (measured)")):
        if n in col:
            style = dict(_MEAS_STYLE, color="tab:green" if n == "gnss_alt" else "0.55")
            ax[0].plot(t, traj.y[:, col[n]], label=lab, **style)
    ax[0].plot(t, -traj.z[:, 0], "k", lw=1.4, label="true altitude")
    ax[0].set_title("Altitude")
    ax[0].set_ylabel("h (m)")

    va = np.hypot(traj.z[:, 1], traj.z[:, 2])
    ax[1].plot(t, va, "k", lw=1.4, label="true airspeed $V_a$")
    ax[1].set_title("Airspeed")
    ax[1].set_ylabel("$V_a$ (m/s)")

    for a, n, i, lab in ((ax[2], "u", 1, "u"), (ax[3], "w", 2, "w")):
        if n in col:
            a.plot(t, traj.y[:, col[n]], label=f"{lab} (measured)", **_MEAS_STYLE)
        a.plot(t, traj.z[:, i], "k", lw=1.4, label=f"true {lab}")
        a.set_ylabel(f"{lab} (m/s)")
    ax[2].set_title("Body velocity u (forward)")
    ax[3].set_title("Body velocity w (down)")

    for a, n, i, unit, title in ((ax[4], "theta", 3, "deg", "Pitch angle"),
                                 (ax[5], "q", 4, "deg/s", "Pitch rate")):
        if n in col:
            a.plot(t, deg(traj.y[:, col[n]]), label=f"{n} (measured)", **_MEAS_STYLE)
        a.plot(t, deg(traj.z[:, i]), "k", lw=1.4, label=f"true {n}")
        a.set_title(title)
        a.set_ylabel(f"({unit})")
    ax[4].plot(t, deg(traj.gamma_cmd), color="tab:blue", lw=1.0, ls="--",
               label=r"$\gamma$ command")

    ax[6].plot(t, deg(traj.u[:, 0]), color="tab:blue", lw=1.2, label=r"$\delta_e$ commanded (deg)")
    ax6b = ax[6].twinx()
    ax6b.plot(t, traj.u[:, 1], color="tab:orange", lw=1.2, ls="--", label=r"$\delta_t$ commanded (0..1)")
    ax[6].set_title("Autopilot inputs")
    ax[6].set_ylabel(r"$\delta_e$ (deg)", color="tab:blue")
    ax6b.set_ylabel(r"$\delta_t$ (-)", color="tab:orange")
    h1, l1 = ax[6].get_legend_handles_labels()
    h2, l2 = ax6b.get_legend_handles_labels()
    ax[6].legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)

    if scenario.faults:
        for j, ch in enumerate(scenario.faults):
            ax[7].plot(t, traj.faults[:, j] / ch.unit_scale, color=_FAULT_COLOURS[j % 6], lw=1.4,
                       label=f"{ch.id}: {ch.kind} fault on {ch.target} ({ch.unit})")
    else:
        ax[7].text(0.5, 0.5, "no faults in this scenario", ha="center", va="center",
                   transform=ax[7].transAxes)
    ax[7].set_title("True faults (shaded on every panel while active)")
    ax[7].set_ylabel("fault (its unit)")

    for a in ax:
        _shade_faults(a, traj, scenario)
        a.grid(True, lw=0.3, alpha=0.6)
        if a is not ax[6] and a.get_legend_handles_labels()[0]:
            a.legend(loc="upper right", fontsize=8)
    for a in axes[-1]:
        a.set_xlabel("time (s)")
    truth = scenario.truth.model + (f" ({scenario.truth.linear_matrices} F, B)"
                                    if scenario.truth.model == "linear" else " (RK4)")
    fig.suptitle(f"{scenario.id}: {scenario.title}\ntruth model {truth}, seed {traj.seed}, "
                 f"autopilot on true state, dt {scenario.dt_s} s", fontsize=11)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
