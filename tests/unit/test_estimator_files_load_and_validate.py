"""Estimator files: the default loads without any experiment, overrides merge, bad keys are named
with the file, and nothing in an estimator file can carry a truth."""

from __future__ import annotations

import math

import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimator_config import (
    DEFAULT_ESTIMATOR,
    estimator_document,
    load_estimator,
    merge_documents,
    parse_estimator,
)


def test_default_estimator_stands_on_its_own():
    est = load_estimator()
    assert est.id == DEFAULT_ESTIMATOR == "aerosonde"
    assert (est.filter, est.particles, est.seed, est.dt_s) == ("RJMRPF", 1000, 0, 0.05)
    assert est.measurements == ("gnss_alt", "baro_alt", "u", "w", "theta", "q")
    assert [f.id for f in est.faults] == ["gnss", "baro", "theta", "q"]
    assert est.faults[2].amplitude_max == pytest.approx(math.radians(20.0))   # deg in the file
    assert (est.operating_point.airspeed_mps, est.operating_point.altitude_m) == (40.0, 500.0)
    # the per-step airframe process noise from the density: sigma sqrt(dt)
    assert est.state_process_std()[3] == pytest.approx(0.001 * math.sqrt(0.05))
    assert est.transition_probabilities() == ((0.01,) * 4, (0.01,) * 4)


def test_a_fault_may_carry_its_own_transition_probabilities():
    doc, _ = estimator_document("aerosonde")
    doc["faults"][1]["pi01"] = 0.001
    est = parse_estimator(doc)
    assert est.transition_probabilities()[0] == (0.01, 0.001, 0.01, 0.01)


def test_overrides_merge_tables_and_replace_lists():
    est = load_estimator("aerosonde", {"particles": 200, "parts": {"jitter": "global"},
                                       "measurements": {"rows": ["theta", "q"],
                                                        "sigma": {"theta": 0.02, "q": 0.004}},
                                       "faults": [{"id": "th", "target": "theta", "unit": "deg",
                                                   "sigma_f": 0.002, "amplitude_max": 10.0}]})
    assert est.particles == 200 and est.settings.jitter == "global"
    assert est.settings.sentinel_weighting == "prior"          # untouched keys stay the file's
    assert est.measurements == ("theta", "q") and [f.id for f in est.faults] == ["th"]
    assert merge_documents({"a": {"b": 1, "c": 2}}, {"a": {"c": 3}}) == {"a": {"b": 1, "c": 3}}


@pytest.mark.parametrize("override, named", [
    ({"parts": {"jiter": "global"}}, "parts.jiter"),
    ({"parts": {"resampler": "stratified"}}, "parts.resampler"),
    ({"filter": "XPF"}, "filter"),
    ({"operating_point": {"airspeed_mps": -3.0}}, "operating_point.airspeed_mps"),
    ({"measurements": {"rows": ["theta", "pitot"]}}, "measurements.rows"),
    ({"truth": {"sigma": 1.0}}, "truth"),                 # no world in an estimator file
    ({"parts": {"sentinel_clip": -3.0}}, "parts.sentinel_clip"),
    ({"parts": {"gain_covariance": "pooled"}}, "parts.gain_covariance"),
    ({"faults": [{"id": "toolongid", "target": "q", "unit": "deg/s", "sigma_f": 0.0}]}, "faults"),
])
def test_bad_keys_are_named_with_the_file(override, named):
    with pytest.raises(ConfigError) as exc:
        load_estimator("aerosonde", override)
    assert "aerosonde.toml" in str(exc.value) and named in str(exc.value)


def test_prior_weighting_needs_every_sensor_fault_range():
    doc, _ = estimator_document("aerosonde")
    del doc["faults"][0]["amplitude_max"]
    with pytest.raises(ConfigError, match="amplitude_max.*gnss"):
        parse_estimator(doc)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="no such estimator file"):
        load_estimator(tmp_path / "nope.toml")


def test_fdir_bench_runs_what_fdir_run_monitors_with_and_states_its_goal(capsys):
    """`fdir bench` without --estimator benchmarks the service's estimator (the robust monitor),
    not the thesis airframe's, and prints the goal for that estimator's RJMRPF / bootstrap ratio."""
    from fdir_service.commands.bench import RATIO_GOALS, bench_estimator, print_bench
    from fdir_service.service_config import load_service_config

    assert bench_estimator().id == load_service_config().estimator.id == "aerosonde-robust"
    assert bench_estimator("aerosonde").id == "aerosonde"
    res = {"cores": 2, "filters": {"RJMRPF": {"1000": 300.0}, "bootstrap": {"1000": 200.0}},
           "mean": {"RJMRPF": {"1000": 360.0}, "bootstrap": {"1000": 200.0}}}
    print_bench(res, "t", RATIO_GOALS["aerosonde-robust"])
    assert "median 1.50, mean 1.80 (goal <= 1.5)" in capsys.readouterr().out
    print_bench(res, "t")
    assert "goal <=" not in capsys.readouterr().out
