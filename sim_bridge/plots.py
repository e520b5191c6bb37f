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
    """Shade, per fault channel, the time spans where it is active (its true value non-zero, or the
    trajectory's recorded activity: a typed fault can be active at value 0)."""
    for j in range(len(scenario.faults)):
        on = np.abs(traj.faults[:, j]) > 0.0 if traj.active is None else traj.active[:, j]
        if not on.any():
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            t1 = traj.t[b] if b < traj.t.size else traj.t[-1]
            ax.axvspan(traj.t[a], t1, color=_FAULT_COLOURS[j % len(_FAULT_COLOURS)], alpha=0.10, lw=0)


def _altitude_panel(ax, traj: Trajectory, col: dict[str, int]) -> None:
    """Altitude: truth, GNSS and barometric measurements."""
    for n, lab in (("gnss_alt", "GNSS altitude (measured)"), ("baro_alt", "baro altitude (measured)")):
        if n in col:
            style = dict(_MEAS_STYLE, color="tab:green" if n == "gnss_alt" else "0.55")
            rows = traj.mask[:, col[n]]                   # a slower sensor: its own samples only
            ax.plot(traj.t[rows], traj.y[rows, col[n]], label=lab, **style)
    ax.plot(traj.t, -traj.z[:, 0], "k", lw=1.4, label="true altitude")
    ax.set_title("Altitude")
    ax.set_ylabel("h (m)")


def _speed_panel(ax, traj: Trajectory, col: dict[str, int], moving_air: bool) -> None:
    """|(u, w)| of the truth (the airspeed in still air, the ground speed in wind) and the pitot."""
    if "airspeed" in col:
        ax.plot(traj.t, traj.y[:, col["airspeed"]], label="airspeed (pitot, measured)", **_MEAS_STYLE)
    label = "true ground speed |(u, w)|" if moving_air else "true airspeed $V_a$"
    ax.plot(traj.t, np.hypot(traj.z[:, 1], traj.z[:, 2]), "k", lw=1.4, label=label)
    ax.set_title("Airspeed and ground speed" if moving_air else "Airspeed")
    ax.set_ylabel("(m/s)")


def _state_panel(ax, traj: Trajectory, col: dict[str, int], name: str, i: int, scale: float,
                 unit: str, title: str) -> None:
    """One airframe state z[:, i] (times scale) with its measurement row, if any."""
    if name in col:
        ax.plot(traj.t, scale * traj.y[:, col[name]], label=f"{name} (measured)", **_MEAS_STYLE)
    ax.plot(traj.t, scale * traj.z[:, i], "k", lw=1.4, label=f"true {name}")
    ax.set_title(title)
    ax.set_ylabel(f"{name} ({unit})" if unit == "m/s" else f"({unit})")


def _input_panel(ax, traj: Trajectory) -> None:
    """Elevator (deg, left axis) and throttle (0..1, right axis) commanded by the autopilot."""
    ax.plot(traj.t, np.degrees(traj.u[:, 0]), color="tab:blue", lw=1.2, label=r"$\delta_e$ commanded (deg)")
    axb = ax.twinx()
    axb.plot(traj.t, traj.u[:, 1], color="tab:orange", lw=1.2, ls="--", label=r"$\delta_t$ commanded (0..1)")
    ax.set_title("Autopilot inputs")
    ax.set_ylabel(r"$\delta_e$ (deg)", color="tab:blue")
    axb.set_ylabel(r"$\delta_t$ (-)", color="tab:orange")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = axb.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)


def _fault_panel(ax, traj: Trajectory, scenario: Scenario) -> None:
    """The world's true faults, each in its unit."""
    for j, ch in enumerate(scenario.faults):
        ax.plot(traj.t, traj.faults[:, j] / ch.unit_scale, color=_FAULT_COLOURS[j % 6], lw=1.4,
                label=f"{ch.id}: {ch.kind} fault on {ch.target} ({ch.unit})")
    if not scenario.faults:
        ax.text(0.5, 0.5, "no faults in this scenario", ha="center", va="center", transform=ax.transAxes)
    ax.set_title("True faults (shaded on every panel while active)")
    ax.set_ylabel("fault (its unit)")


def plot_run(traj: Trajectory, scenario: Scenario, path: str | Path) -> Path:
    """Write a 4x2 figure of the run to `path` (PNG or anything matplotlib saves); returns the path."""
    col = {n: i for i, n in enumerate(scenario.sensors.measurements)}
    fig, axes = plt.subplots(4, 2, figsize=(13, 11), sharex=True)
    ax = axes.ravel()
    _altitude_panel(ax[0], traj, col)
    _speed_panel(ax[1], traj, col, scenario.sky.moving_air)
    _state_panel(ax[2], traj, col, "u", 1, 1.0, "m/s", "Body velocity u (forward)")
    _state_panel(ax[3], traj, col, "w", 2, 1.0, "m/s", "Body velocity w (down)")
    _state_panel(ax[4], traj, col, "theta", 3, np.degrees(1.0), "deg", "Pitch angle")
    _state_panel(ax[5], traj, col, "q", 4, np.degrees(1.0), "deg/s", "Pitch rate")
    ax[4].plot(traj.t, np.degrees(traj.gamma_cmd), color="tab:blue", lw=1.0, ls="--",
               label=r"$\gamma$ command")
    _input_panel(ax[6], traj)
    _fault_panel(ax[7], traj, scenario)
    for a in ax:
        _shade_faults(a, traj, scenario)
        a.grid(True, lw=0.3, alpha=0.6)
        if a is not ax[6] and a.get_legend_handles_labels()[0]:
            a.legend(loc="upper right", fontsize=8)
    for a in axes[-1]:
        a.set_xlabel("time (s)")
    truth = scenario.truth.model + (f" ({scenario.truth.linear_matrices} F, B)"
                                    if scenario.truth.model == "linear" else " (RK4)")
    if scenario.sky.engine == "jsbsim":
        truth = "JSBSim 6-DOF (config/jsbsim)"
    fig.suptitle(f"{scenario.id}: {scenario.title}\ntruth model {truth}, seed {traj.seed}, "
                 f"autopilot on true state, dt {scenario.dt_s} s", fontsize=11)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
