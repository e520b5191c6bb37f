"""The catalogue estimator in moderate turbulence, flying (closed loop) through an actuator fault
of each type at 10 s: the engine quits (its thrust to 0), the elevator binds where it is, the
elevator keeps 30 % of its deflection. The item is declared as the service would (its P over its
types, the declare hysteresis) within the issue's 2 s, the engine loss as the throttle's loss of
effectiveness with the gain the world's engine leaves."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared

ONSET_S = 10.0


def flight(world: str, fault_id: str, amplitude: float, end_s: float, seconds: float = 20.0):
    """(trajectory, scenario) of `world` with only `fault_id` at ONSET_S..end_s, run 1."""
    sc = load_scenario(world)
    ch = next(f for f in sc.faults if f.id == fault_id)
    comp = dataclasses.replace(ch.profile[0], start_s=ONSET_S, end_s=end_s, amplitude=amplitude,
                               varies=(), random_sign=False)
    sc = dataclasses.replace(sc, faults=(dataclasses.replace(ch, profile=(comp,)),), duration_s=seconds)
    return fly(sc, "RJMRPF", 1), sc


def first_declaration(tr, sc, target: str) -> tuple[float, str, float, str]:
    """(time s, type, user-facing value 1 s later, type 2 s later) of the first declaration of the
    item watching target."""
    entries = [kind_of(f) for f in sc.estimator.faults]
    names = [f.id for f in sc.estimator.faults]
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, entries, names)
    i = view.targets.index(target)
    k = int(np.flatnonzero(declared(tr.t, view.prob[:, i], Hysteresis()))[0])
    j = int(view.best[k, i])
    settle = min(k + 20, len(tr.t) - 1)                  # the value 1 s after the declaration
    later = int(view.best[min(k + 40, len(tr.t) - 1), i])
    return float(tr.t[k]), entries[j].type, float(tr.outputs[settle].value_of(j)), entries[later].type


def test_an_engine_that_quits_is_declared_within_2_s_with_the_gain_it_leaves():
    tr, sc = flight("real-engine", "dt_eff", 0.0, 16.0)
    t, kind, _, settled = first_declaration(tr, sc, "delta_t")
    assert ONSET_S <= t < ONSET_S + 2.0
    # at a steady command a lost gain is an offset: the kind is told as the autopilot opens the throttle
    assert kind in ("bias", "effectiveness") and settled == "effectiveness"
    # zero thrust is the throttle V / k_m (~0.5 of the saturated command in the model's propeller,
    # SPEC section 2): the gain read over the fault's last 2 s is the one the world applied
    j = [f.id for f in sc.estimator.faults].index("dt_eff")
    late = (tr.t >= 14.0) & (tr.t < 16.0)
    read = np.mean([tr.outputs[k].value_of(j) for k in np.flatnonzero(late)])
    applied = np.mean(1.0 + tr.faults[late, 0] / tr.u[late, 1])
    assert 0.3 < applied < 0.7 and abs(read - applied) < 0.1


@pytest.mark.parametrize("run", [1, 2, 3, 4])
def test_an_engine_that_comes_back_leaves_the_pitot_undeclared(run):
    """Without an airspeed hold that lets go at full throttle the pitot was blamed for the airspeed
    the engine lost and regained (docs/faults.md, "The hold needs the throttle")."""
    _, sc = flight("real-engine", "dt_eff", 0.0, 18.0, seconds=32.0)
    tr = fly(sc, "RJMRPF", run)
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, [kind_of(f) for f in sc.estimator.faults], [f.id for f in sc.estimator.faults])
    i = view.targets.index("airspeed")
    assert not declared(tr.t, view.prob[:, i], Hysteresis())[tr.t >= 18.0 + 3.0].any()


@pytest.mark.parametrize("fault_id, amplitude, end_s", [("de_jam", 0.0, 14.0), ("de_eff", 0.3, 18.0)])
def test_an_elevator_that_binds_or_weakens_is_declared_within_2_s(fault_id, amplitude, end_s):
    tr, sc = flight("real-actuators", fault_id, amplitude, end_s)
    t, kind, _, _ = first_declaration(tr, sc, "delta_e")
    assert ONSET_S <= t < ONSET_S + 2.0
    assert kind in ("bias", "jammed", "effectiveness")
