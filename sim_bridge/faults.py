"""True fault time courses of a scenario (SPEC section 7; semantics in `ProfileComponent`).

Each fault channel's value is the sum of its profile components, in SI units (m, rad, rad/s, ...):
- step: `amplitude` on [start_s, end_s);
- exponential: amplitude * exp((t - end_s) / tau_s) on [start_s, end_s);
- ramp: 0 at start_s rising linearly to `amplitude` at end_s, on [start_s, end_s), 0 after;
- intermittent: amplitude during on_s, then 0 during off_s, repeating from start_s until end_s.
Interval edges are compared with a 1e-9 s tolerance so that frame times k * dt that land on a
key time up to rounding (e.g. 200 * 0.05) fall on the intended side.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from sim_bridge.scenario import FaultChannel, ProfileComponent, Scenario

EDGE_TOL_S = 1e-9


def component_value(comp: ProfileComponent, t: float | np.ndarray) -> np.ndarray:
    """Value (SI) of one profile component at time(s) t (s); array of t's shape."""
    t = np.asarray(t, dtype=float)
    active = (t >= comp.start_s - EDGE_TOL_S) & (t < comp.end_s - EDGE_TOL_S)
    if comp.shape == "step":
        val = np.full(t.shape, comp.amplitude)
    elif comp.shape == "exponential":
        val = comp.amplitude * np.exp(np.minimum(t - comp.end_s, 0.0) / comp.tau_s)
    elif comp.shape == "ramp":
        frac = np.clip((t - comp.start_s) / (comp.end_s - comp.start_s), 0.0, 1.0)
        val = comp.amplitude * frac
    elif comp.shape == "intermittent":
        phase = np.mod(t - comp.start_s + EDGE_TOL_S, comp.on_s + comp.off_s)
        val = np.where(phase < comp.on_s, comp.amplitude, 0.0)
    else:  # the scenario loader only admits the four shapes above
        raise ValueError(f"unknown fault profile shape {comp.shape!r}")
    return np.where(active, val, 0.0)


def _component_scalar(comp: ProfileComponent, t: float) -> float:
    """component_value for one float t, in Python floats (the simulator's per-frame path)."""
    if not (comp.start_s - EDGE_TOL_S <= t < comp.end_s - EDGE_TOL_S):
        return 0.0
    if comp.shape == "step":
        return float(comp.amplitude)
    if comp.shape == "exponential":
        return comp.amplitude * math.exp(min(t - comp.end_s, 0.0) / comp.tau_s)
    if comp.shape == "ramp":
        frac = (t - comp.start_s) / (comp.end_s - comp.start_s)
        return comp.amplitude * min(max(frac, 0.0), 1.0)
    if comp.shape == "intermittent":
        phase = (t - comp.start_s + EDGE_TOL_S) % (comp.on_s + comp.off_s)
        return float(comp.amplitude) if phase < comp.on_s else 0.0
    raise ValueError(f"unknown fault profile shape {comp.shape!r}")


def channel_value(channel: FaultChannel, t: float | np.ndarray) -> float | np.ndarray:
    """The channel's true fault value(s) (SI) at time(s) t (s): sum of its profile components.

    A scalar t gives a float, an array of times an array of the same shape.
    """
    if isinstance(t, (float, int)):
        total = 0.0
        for comp in channel.profile:
            total = total + _component_scalar(comp, float(t))
        return total
    tt = np.asarray(t, dtype=float)
    total = np.zeros(tt.shape)
    for comp in channel.profile:
        total = total + component_value(comp, tt)
    return float(total) if total.ndim == 0 else total


def component_active(comp: ProfileComponent, t: float) -> bool:
    """Whether one profile component is active at t (s): inside [start_s, end_s) and, for an
    intermittent component, in an on phase (a typed fault acts only while active)."""
    if not (comp.start_s - EDGE_TOL_S <= t < comp.end_s - EDGE_TOL_S):
        return False
    if comp.shape == "intermittent":
        return (t - comp.start_s + EDGE_TOL_S) % (comp.on_s + comp.off_s) < comp.on_s
    return True


def channel_active(channel: FaultChannel, t: float) -> bool:
    """Whether any of the channel's profile components is active at t (s)."""
    return any(component_active(c, float(t)) for c in channel.profile)


def fault_activity(scenario: Scenario, t: float) -> np.ndarray:
    """(nf,) bool: each fault's profile active at t (s), in the scenario's fault order."""
    return np.array([channel_active(ch, t) for ch in scenario.faults], dtype=bool)


def fault_vector(scenario: Scenario, t: float) -> np.ndarray:
    """All fault values (nf,) at time t (s), SI, in the scenario's fault order."""
    return np.array([channel_value(ch, t) for ch in scenario.faults], dtype=float)


def fault_active_intervals(scenario: Scenario) -> list[tuple[str, float, float]]:
    """(fault id, start_s, end_s) of every profile component, for plots and summaries (an
    intermittent component's off phases included)."""
    return [(ch.id, c.start_s, c.end_s) for ch in scenario.faults for c in ch.profile]


def _drawn(comp: ProfileComponent, rng: np.random.Generator) -> ProfileComponent:
    """One run's component: its varying fields drawn uniformly, in declaration order, then the sign."""
    vals = {name: float(rng.uniform(lo, hi)) for name, lo, hi in comp.varies}
    start = vals.get("start_s", comp.start_s)
    end = start + vals["duration_s"] if "duration_s" in vals else comp.end_s
    amplitude = vals.get("amplitude", comp.amplitude)
    if comp.random_sign and rng.random() < 0.5:
        amplitude = -amplitude
    return dataclasses.replace(comp, start_s=start, end_s=max(end, start + 1e-6), amplitude=amplitude,
                               varies=(), random_sign=False)


def vary_profiles(scenario: Scenario, rng: np.random.Generator) -> Scenario:
    """The scenario with one run's draw of every varying fault profile (start, duration, amplitude,
    sign: `ProfileComponent.varies`); the scenario itself when nothing varies (no draws)."""
    if not any(c.varies or c.random_sign for ch in scenario.faults for c in ch.profile):
        return scenario
    faults = tuple(dataclasses.replace(ch, profile=tuple(_drawn(c, rng) for c in ch.profile))
                   for ch in scenario.faults)
    return dataclasses.replace(scenario, faults=faults)
