"""The catalogue estimator in moderate turbulence, flying (closed loop) through an actuator fault
of each type at 10 s: the engine quits (its thrust to 0), the elevator binds where it is, the
elevator keeps 30 % of its deflection. The item is declared as the service would (its P over its
types, the declare hysteresis) within the issue's 2 s; the engine loss is named an engine (the
service's type naming) with the thrust it leaves, where without the engine entry it is a lost gain
or an offset of the throttle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.estimator_config import parse_estimator
from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of, named_entry
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


def named_type(tr, sc, target: str) -> tuple[float, str | None]:
    """(time s of the first declaration of the item watching target, the type the service names for
    it: `type_yardstick.named_entry`, None if it never names one)."""
    entries = [kind_of(f) for f in sc.estimator.faults]
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, entries, [f.id for f in sc.estimator.faults])
    i = view.targets.index(target)
    dec = declared(tr.t, view.prob[:, i], Hysteresis())
    k0 = int(np.flatnonzero(dec)[0])
    named = named_entry(tr.t, dec, view, i, k0, Hysteresis())
    return float(tr.t[k0]), None if named is None else entries[named[1]].type


def without_engine_entry(sc):
    """The scenario with its estimator's engine entry removed (the catalogue before the engine type)."""
    est = sc.estimator
    doc = dict(est.doc, faults=[f for f in est.doc["faults"] if f.get("type") != "engine"])
    return dataclasses.replace(sc, estimator=parse_estimator(doc, "without-engine"))


@pytest.mark.parametrize("run", [1, 2, 3])
def test_an_engine_that_quits_is_named_an_engine_within_2_s_with_no_thrust_left(run):
    _, sc = flight("real-engine", "dt_eff", 0.0, 16.0)
    tr = fly(sc, "RJMRPF", run)
    t, kind = named_type(tr, sc, "delta_t")
    assert ONSET_S <= t < ONSET_S + 2.0
    assert kind == "engine"
    # the engine gives no thrust: the share of the commanded thrust read over the fault's last 2 s
    j = [f.id for f in sc.estimator.faults].index("dt_eng")
    late = (tr.t >= 14.0) & (tr.t < 16.0)
    assert np.mean([tr.outputs[k].value_of(j) for k in np.flatnonzero(late)]) < 0.15


def test_without_the_engine_entry_the_same_loss_is_named_another_type():
    """What the engine entry changes: the catalogue without it declares the same engine loss in time
    but names it a lost gain or an offset of the throttle (or nothing sure)."""
    _, sc = flight("real-engine", "dt_eff", 0.0, 16.0)
    sc = without_engine_entry(sc)
    t, kind = named_type(fly(sc, "RJMRPF", 1), sc, "delta_t")
    assert ONSET_S <= t < ONSET_S + 2.0
    assert kind in ("bias", "effectiveness", None)


def test_an_engine_that_comes_back_leaves_the_pitot_undeclared_on_6_of_8_flights():
    """Without an airspeed hold that lets go at full throttle the pitot was blamed for the airspeed
    the engine lost and regained, on nearly every flight (docs/faults.md, "The hold needs the
    throttle"). A gust while the aircraft slows is still sometimes cheaper as a pitot bias, which
    then outlives the loss, as in 5-7 of real-engine's 100 flights. Which flights turns on the
    cloud's path: before the stuck sensors' held values were learnt (held_mean.py) run 2 here, and
    none of runs 9-14; since, runs 2 and 4, and none of runs 9-13."""
    _, sc = flight("real-engine", "dt_eff", 0.0, 18.0, seconds=32.0)
    standing = []
    for run in range(1, 9):
        tr = fly(sc, "RJMRPF", run)
        P = np.array([o.fault_probability for o in tr.outputs])
        view = item_view(P, [kind_of(f) for f in sc.estimator.faults], [f.id for f in sc.estimator.faults])
        i = view.targets.index("airspeed")
        if declared(tr.t, view.prob[:, i], Hysteresis())[tr.t >= 18.0 + 3.0].any():
            standing.append(run)
    assert len(standing) <= 2, standing


@pytest.mark.parametrize("run", [1, 2, 3, 4])
def test_a_jam_whose_command_runs_to_its_stop_leaves_the_state_tracked(run):
    """The autopilot, which cannot know the surface is bound, runs the elevator command towards its 30 deg
    stop (25-30 deg before stop 44; 24.8 on run 3 with a stop-44 variant that kept the learnt pitch-
    rate noise under a fault); the jam's entry (held position minus command) grows past its onset
    prior (amplitude_max 15 deg) towards its value_max (60 deg). With every entry clipped at its
    prior, as before value_max, 3 of these 4 flights lost the state during the jam (altitude 6-25 m,
    w 9-15 m/s off: the gyro or the attitude was blamed for what the clipped jam could not explain);
    the jam's clip alone, 1."""
    _, sc = flight("real-actuators", "de_jam", 0.0, 15.0, seconds=15.5)
    tr = fly(sc, "RJMRPF", run)
    jam = (tr.t >= ONSET_S) & (tr.t < 15.0)
    assert np.degrees(np.abs(tr.u[jam, 0]).max()) > 20.0          # far past the jam's onset prior
    error = np.abs(tr.z - np.array([o.x_mean[:5] for o in tr.outputs]))[jam]
    assert error[:, 0].max() < 3.0 and error[:, 2].max() < 3.0      # altitude m, w m/s


@pytest.mark.parametrize("fault_id, amplitude, end_s", [("de_jam", 0.0, 14.0), ("de_eff", 0.3, 18.0)])
def test_an_elevator_that_binds_or_weakens_is_declared_within_2_s(fault_id, amplitude, end_s):
    tr, sc = flight("real-actuators", fault_id, amplitude, end_s)
    t, kind, _, _ = first_declaration(tr, sc, "delta_e")
    assert ONSET_S <= t < ONSET_S + 2.0
    assert kind in ("bias", "jammed", "effectiveness")


def test_a_bind_that_releases_at_the_stop_leaves_the_attitude_tracked():
    """When the bind releases, the surface snaps to the command at its stop and the aircraft pitches
    at 50-70 deg/s within a frame. With theta + q dt, q held over the frame, the integrated attitude
    lagged by dt (q+ - q) / 2 per frame: 1.0-2.5 deg off 1 s after the release on 6 of these 8
    flights, and the attitude declared (drifting) on 4. With the trapezoid of the gyro-corrected
    rates (`KinematicProcess.close_frame`) 0.14-0.64 deg, declared on 2 (runs 5 and 8). Since the
    drift entries hand over less (docs/faults.md, "Hand-overs out of a drift") 0.23-1.04 deg,
    declared on none: on run 1 the gyro's bias takes the blame for the snap for a second (as it
    can on any flight: the cloud's path differs), 1.04 deg at 16 s. Since the stuck sensors' held
    values are learnt (held_mean.py) 0.13-1.63 deg, over 1 deg on runs 1 (the gyro's bias again,
    with the attitude's drift and the elevator's and throttle's effectiveness, traced) and 5; on
    runs 9-18 0.17-0.61 deg, where the build before gave 0.16-0.84 and 5.03 deg on run 14 (the
    attitude declared). Asserted: at most 2 of 8 over 1 deg, none over 2 deg."""
    _, sc = flight("real-actuators", "de_jam", 0.0, 15.0, seconds=19.0)
    entries = [kind_of(f) for f in sc.estimator.faults]
    worst, standing = [], 0
    for run in range(1, 9):
        tr = fly(sc, "RJMRPF", run)
        after = tr.t >= 15.0
        assert np.degrees(np.abs(np.diff(tr.z[after, 4])).max()) > 40.0      # the snap: q jumps
        error = np.degrees(np.abs(tr.z[:, 3] - np.array([o.x_mean[3] for o in tr.outputs])))
        worst.append(error[tr.t >= 16.0].max())
        view = item_view(np.array([o.fault_probability for o in tr.outputs]), entries,
                         [f.id for f in sc.estimator.faults])
        standing += declared(tr.t, view.prob[:, view.targets.index("theta")], Hysteresis())[after].any()
    assert sorted(worst)[-3] < 1.0 and max(worst) < 2.0, np.round(worst, 2)   # 6 of 8 over 1.0 before
    assert standing <= 2
