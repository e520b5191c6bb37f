"""Items a flight declares, by the service's rule (P(item) over its types, the declare hysteresis)."""

from __future__ import annotations

import numpy as np

from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared

ATTITUDE_BEFORE_STOP_51 = {"sigma_x": (0.02, 0.1, 0.15, 0.002, 0.15), "frame_angle": "trapezoid"}
"""The catalogue's attitude when the flights its behaviour tests pin were traced: theta's process
noise 0.002 rad/sqrt(s) and the trapezoid everywhere (0.001 and "snap" since stop 51; docs/faults.md,
"The attitude's process noise"). Those tests keep it, so that each flight fails, or is mended, the
way it was traced."""

MEMORY_BEFORE_STOP_52 = {"fault_free_memory": "entry", "fault_free_rollback_s": 0.0}
"""The catalogue's fault-free value before stop 52: every entry's from its own mode-0 particles, as
it stands (since stop 52 an input's from the particles whose whole input is fault-free, frozen at
its value from 2 s before the fault won; docs/faults.md, "The fault-free value from before the
onset")."""

MEMORY_AT_STOP_52 = {"fault_free_memory": "input_item", "fault_free_rollback_s": 2.0}
"""The catalogue's fault-free value at stop 52: an input's by item, a sensor's by entry, frozen at
its value from 2 s before the fault won (since stop 53 every entry's by item)."""

TRACED_BEFORE_STOP_52 = {**ATTITUDE_BEFORE_STOP_51, **MEMORY_BEFORE_STOP_52}
"""The catalogue as the flights its behaviour tests pin were traced: its attitude before stop 51 and
its fault-free value before stop 52. Those tests keep it, so that each flight fails, or is mended,
the way it was traced."""


def first_declarations(faults, tr) -> dict[str, float]:
    """{item: first declared frame's time (s)} of a flight `tr` (its outputs' fault_probability)
    monitored with the estimator fault entries `faults` (`FaultSpec`s)."""
    view = _items(faults, tr)
    found = {}
    for i, item in enumerate(view.names):
        k = np.flatnonzero(declared(tr.t, view.prob[:, i], Hysteresis()))
        if k.size:
            found[item] = float(tr.t[k[0]])
    return found


def _flown(world: str, run: int, seconds: float, **parts):
    """(scenario, flight) of `world`'s run `run` (campaign seed 0, the monitor loop) flown to
    `seconds` with the estimator's [parts] settings `parts`."""
    import dataclasses

    from sim_bridge.campaign import fly
    from sim_bridge.scenario import load_scenario

    sc = load_scenario(world)
    est = dataclasses.replace(sc.estimator, settings=dataclasses.replace(sc.estimator.settings, **parts))
    return sc, fly(dataclasses.replace(sc, estimator=est, duration_s=seconds), "RJMRPF", run, 0)


def _items(faults, tr):
    """The flight's `ItemView`: P(item) over its types per frame."""
    P = np.array([o.fault_probability for o in tr.outputs])
    return item_view(P, [kind_of(f) for f in faults], [f.id for f in faults])


def fly_with_parts(world: str, run: int, seconds: float, **parts) -> tuple[dict[str, float], float]:
    """({item: first declared (s)}, the largest altitude error (m)) of `world`'s run `run` (campaign
    seed 0, the monitor loop) flown to `seconds` with the estimator's [parts] settings `parts`."""
    sc, tr = _flown(world, run, seconds, **parts)
    altitude = np.array([o.x_mean[0] for o in tr.outputs])
    return first_declarations(sc.estimator.faults, tr), float(np.abs(altitude - tr.z[:, 0]).max())


def declared_when_quiet(world: str, run: int, seconds: float, **parts) -> dict[str, float]:
    """{item: seconds declared while no fault is active nor ended within the yardstick's grace} of
    `world`'s run `run` flown as `fly_with_parts` flies it: the false alarms' time, by the
    service's rule."""
    from sim_bridge.yardstick import quiet_mask

    sc, tr = _flown(world, run, seconds, **parts)
    view = _items(sc.estimator.faults, tr)
    quiet = quiet_mask(tr.t, tr.active.any(axis=1))
    dt = float(tr.t[1] - tr.t[0])
    out = {}
    for i, item in enumerate(view.names):
        frames = int(np.count_nonzero(declared(tr.t, view.prob[:, i], Hysteresis()) & quiet))
        if frames:
            out[item] = frames * dt
    return out
