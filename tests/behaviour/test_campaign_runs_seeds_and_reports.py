"""Campaign machinery (sim_bridge.campaign, sim_bridge.report) with small fake filters on the real
closed-loop simulator: seeds, determinism across process pools and dask, results.json structure."""

import json

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from sim_bridge.campaign import (
    GATE,
    campaign_filters,
    filter_rng,
    make_jobs,
    run_campaign,
    run_job,
    sim_seed,
)
from sim_bridge.report import COLUMNS, check_orderings, summarise, write_report

NOISE = {"JMRPF": 0.5, "IMM-KF": 5.0, GATE: 1.0}


class MeasuredFilter:
    """Estimates straight from the measurements plus noise of a per-name size (no model)."""

    def __init__(self, name, scenario, rng):
        self.name, self.rng = name, rng
        self.fault_ids = tuple(f.id for f in scenario.faults)
        self.noise = NOISE[name]
        self.calls = 0

    def step(self, t, y, mask, u):
        self.calls += 1
        baro = y[1]
        z = np.array([-baro, y[2], y[3], y[4], y[5]])
        # a fault estimate: the true fault profile, known here only to make the test's RMSE exact
        f_true = np.array([50.0 * (10 <= t < 30), 30.0 * (20 <= t < 40)])
        f_hat = f_true + self.noise * self.rng.standard_normal(2)
        if self.name == GATE:
            f_hat = np.full(2, np.nan)
        prob = (f_true > 0).astype(float)
        x = np.concatenate([z, f_hat])
        return StepOutput(t, x, np.eye(7), self.fault_ids, f_hat, prob, 100.0, False)

    def top_particles(self, k=20):
        x = np.repeat(np.concatenate([[0.0] * 5, [1.0, 2.0]])[None, :], 3, 0)
        return x, np.array([0.5, 0.3, 0.2])


def fake_builder(name, scenario, rng, particles=None):
    return MeasuredFilter(name, scenario, rng)


def test_seeds_common_noise_per_run_and_own_stream_per_filter():
    assert sim_seed(0, 3) == sim_seed(0, 3)
    assert len({sim_seed(0, r) for r in range(50)}) == 50
    assert sim_seed(0, 1) != sim_seed(1, 1)
    a = filter_rng(0, 2, "JMRPF").standard_normal(3)
    np.testing.assert_array_equal(a, filter_rng(0, 2, "JMRPF").standard_normal(3))
    assert not np.allclose(a, filter_rng(0, 2, "IMM-KF").standard_normal(3))
    assert not np.allclose(a, filter_rng(0, 3, "JMRPF").standard_normal(3))


def test_campaign_filters_add_the_gate(ch4):
    assert campaign_filters(ch4) == ("JMRPF", "IMM-KF", GATE)
    jobs = make_jobs(ch4, 2, seed=5)
    assert [(j.filter, j.run) for j in jobs[:3]] == [("JMRPF", 0), ("IMM-KF", 0), (GATE, 0)]
    assert len(jobs) == 6


def test_run_job_records_the_run(ch4):
    job = make_jobs(ch4, 1, seed=1, builder=fake_builder)[0]
    res = run_job(job)
    K = ch4.steps
    assert res.t.shape == (K,) and res.z_true.shape == (K, 5) and res.f_hat.shape == (K, 2)
    assert res.top_x.shape == (50, 20, 7)          # one snapshot per whole second
    np.testing.assert_array_equal(res.top_t[:3], [0.0, 1.0, 2.0])
    assert np.isnan(res.top_w[:, 3:]).all() and np.allclose(res.top_w[:, :3].sum(1), 1.0)
    # the fault truth is the scenario's profile: gnss +50 m on 10-30 s
    assert res.f_true[res.t.searchsorted(15.0), 0] == pytest.approx(50.0)
    assert res.f_true[res.t.searchsorted(35.0), 0] == 0.0
    assert res.pfa is None and res.filter_s > 0


def test_pool_and_inline_give_identical_results_and_common_noise(ch4):
    a = run_campaign(ch4, 2, seed=7, workers=1, progress=False, builder=fake_builder)
    b = run_campaign(ch4, 2, seed=7, workers=2, progress=False, builder=fake_builder)
    for name in a.filters:
        np.testing.assert_array_equal(a.filters[name].f_hat, b.filters[name].f_hat)
        np.testing.assert_array_equal(a.filters[name].z_true, b.filters[name].z_true)
    # run r has the same simulator seed (sensor noise) for every filter
    seeds = {n: tuple(fr.sim_seeds) for n, fr in a.filters.items()}
    assert len(set(seeds.values())) == 1
    # different filter streams: the fault-estimate noise differs between filters
    assert not np.allclose(a.filters["JMRPF"].f_hat / 0.5, a.filters["IMM-KF"].f_hat / 5.0)


def test_dask_local_cluster_matches_local(ch4):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        d = run_campaign(ch4, 2, seed=7, dask=cluster.scheduler_address, progress=False,
                         builder=fake_builder)
    a = run_campaign(ch4, 2, seed=7, workers=1, progress=False, builder=fake_builder)
    for name in a.filters:
        np.testing.assert_array_equal(a.filters[name].f_hat, d.filters[name].f_hat)


def test_results_json_structure_and_values(ch4, tmp_path):
    camp = run_campaign(ch4, 3, seed=2, workers=1, progress=False, builder=fake_builder)
    doc = write_report(camp, tmp_path, make_figures=True)
    on_disk = json.loads((tmp_path / "results.json").read_text())
    assert on_disk == json.loads(json.dumps(doc))
    assert set(on_disk) >= {"scenario", "runs", "particles", "seed", "filters"}
    assert on_disk["scenario"] == "ch4" and on_disk["runs"] == 3 and on_disk["seed"] == 2
    assert set(on_disk["filters"]) == {"JMRPF", "IMM-KF", GATE}
    for _name, fd in on_disk["filters"].items():
        assert set(fd["rmse"]) == {"p_d", "u", "w", "theta", "q", "f_gnss", "f_baro"}
        for cols in fd["rmse"].values():
            assert set(cols) == set(COLUMNS)
        assert set(fd["detection"]) == {"gnss", "baro"}
        for d in fd["detection"].values():
            assert {"delay_s", "false_alarm_fraction", "missed_fraction"} <= set(d)
        assert fd["runtime_s"] > 0
    # fault RMSE of a N(0, s^2) error is ~s: 0.5 m for "JMRPF", 5 m for "IMM-KF" (3 runs x 1000 steps)
    assert on_disk["filters"]["JMRPF"]["rmse"]["f_gnss"]["mean"] == pytest.approx(0.5, rel=0.1)
    assert on_disk["filters"]["IMM-KF"]["rmse"]["f_baro"]["mean"] == pytest.approx(5.0, rel=0.1)
    assert on_disk["filters"][GATE]["rmse"]["f_gnss"]["mean"] is None     # no magnitude
    # P(fault) is exactly the truth's support: zero delay, no false alarm, no missed detection
    det = on_disk["filters"]["JMRPF"]["detection"]["baro"]
    assert det["delay_s"] == 0.0 and det["false_alarm_fraction"] == 0.0 and det["missed_fraction"] == 0.0
    # theta in degrees: the measured pitch has 0.01 rad noise -> ~0.573 deg RMSE
    assert 0.4 < on_disk["filters"]["JMRPF"]["rmse"]["theta"]["mean"] < 0.65  # closed loop: a bit below
    report = (tmp_path / "report.md").read_text()
    assert "| f_gnss | m |" in report and "thesis mean" in report
    # what decides the bits is recorded: numpy's SIMD kernels (pinned by make), the BLAS kernel, the code
    env = on_disk["environment"]
    assert {"numpy", "machine", "numpy_simd", "blas_core", "commit"} <= set(env)
    assert "AVX512" not in env["numpy_simd"] and "X86_V4" not in env["numpy_simd"]
    assert env["blas_core"] and env["commit"]
    assert f"numpy SIMD {env['numpy_simd']}" in report or not env["numpy_simd"]
    for png in ("fault_estimates_median.png", "rmse_faults.png", "rmse_states.png", "top_particles.png"):
        assert (tmp_path / png).stat().st_size > 10_000
    orders = check_orderings({"ch4": on_disk})
    assert [o["holds"] for o in orders] == [True, True, False]  # p_d: both read the same barometer
    assert summarise(camp)["filters"]["JMRPF"]["median_run"] in (0, 1, 2)


def failing_builder(name, scenario, rng, particles=None):
    if name == "IMM-KF":
        raise np.linalg.LinAlgError("Singular matrix")
    return MeasuredFilter(name, scenario, rng)


def broken_step_builder(name, scenario, rng, particles=None):
    filt = MeasuredFilter(name, scenario, rng)
    filt.step = None          # a TypeError at the first step
    return filt


def test_a_filter_whose_every_run_fails_stops_the_campaign_with_its_error(ch4):
    with pytest.raises(RuntimeError, match="every run of IMM-KF failed.*Singular"):
        run_campaign(ch4, 2, seed=1, workers=1, progress=False, builder=failing_builder,
                     filters=("JMRPF", "IMM-KF"))


def test_failed_runs_are_reported_and_left_out_of_the_statistics(ch4):
    from sim_bridge import campaign as cm
    ok = cm.run_job(cm.make_jobs(ch4, 1, seed=1, builder=fake_builder, filters=("JMRPF",))[0])
    bad = cm.run_job(cm.make_jobs(ch4, 2, seed=1, builder=broken_step_builder, filters=("JMRPF",))[1])
    assert isinstance(bad, cm.RunFailure) and bad.run == 1 and "TypeError" in bad.error
    fr = cm.stack_runs([bad, ok])
    assert fr.f_hat.shape[0] == 2 and np.isnan(fr.f_hat[1]).all() and np.isfinite(fr.f_hat[0]).all()
    assert [f.run for f in fr.failures] == [1]
    doc = summarise(cm.Campaign(ch4, 2, 1000, 1, {"JMRPF": fr}))["filters"]["JMRPF"]
    assert doc["failed_runs"][0]["run"] == 1 and doc["median_run"] == 0
    # one surviving run: RMSE_k = |error|, whose time mean is 0.5 sqrt(2 / pi) for N(0, 0.5^2)
    assert doc["rmse"]["f_gnss"]["mean"] == pytest.approx(0.5 * np.sqrt(2 / np.pi), rel=0.1)
    assert doc["detection"]["gnss"]["missed_fraction"] == 0.0


def test_report_explains_misses_and_publishes_into_docs(ch4, tmp_path, monkeypatch):
    """A miss against the thesis prints its investigated reason (or says it was not investigated);
    publish copies the scenario folder to DOCS/results/<id>/, rewrites its report.md and
    regenerates DOCS/results.md (status, misses, figure links)."""
    from sim_bridge import report as rep
    from sim_bridge.report import EXPLANATIONS, READING_NOTES, publish

    monkeypatch.setitem(rep.EXPLANATIONS, ("ch4", "f_gnss"), "Why: the GNSS test reason, measured.")
    monkeypatch.setitem(rep.EXPLANATIONS, ("ch4", "f_baro"), "Why: the baro test reason, measured.")
    camp = run_campaign(ch4, 2, seed=1, workers=1, progress=False, builder=fake_builder,
                        filters=("JMRPF", GATE))
    camp.filters["JMRPF"].f_hat[:] += 20.0          # far above the thesis's 1.26 m / 0.72 m
    write_report(camp, tmp_path / "results" / "ch4", make_figures=False)
    report = (tmp_path / "results" / "ch4" / "report.md").read_text()
    assert "**Miss on f_gnss**" in report and EXPLANATIONS[("ch4", "f_gnss")][:40] in report
    assert READING_NOTES[0][:30] in report
    page = publish(tmp_path / "results", tmp_path / "docs")
    assert page == tmp_path / "docs" / "results.md"
    assert (tmp_path / "docs" / "results" / "ch4" / "results.json").exists()
    text = page.read_text()
    assert "**Status: interim**" in text and "| ch4 | 2 |" in text
    assert "## Where we miss, and why" in text and EXPLANATIONS[("ch4", "f_baro")][:40] in text
    assert "## Where we depart from the thesis" in text
    monkeypatch.delitem(rep.EXPLANATIONS, ("ch4", "f_baro"))
    publish(tmp_path / "results", tmp_path / "docs")     # report.md rewritten from results.json
    again = (tmp_path / "docs" / "results" / "ch4" / "report.md").read_text()
    assert "**Miss on f_baro**" in again and "Reason: not investigated yet." in again


def test_an_estimator_watching_faults_the_world_never_injects_is_scored_per_estimated_fault(ch4, tmp_path):
    """The default estimator (gnss, baro, theta, q) on the ch4 world (gnss, baro injected): its theta
    and q rows are scored against a zero truth (false alarms only), nothing is misaligned."""
    import dataclasses

    from fdir_service.estimator_config import load_estimator

    sc = dataclasses.replace(ch4, estimator=load_estimator().with_filter("RJMRPF", particles=200),
                             filters=("RJMRPF",), proposed="RJMRPF")
    camp = run_campaign(sc, 1, seed=0, workers=1, progress=False)
    doc = write_report(camp, tmp_path, make_figures=True)
    fd = doc["filters"]["RJMRPF"]
    assert set(fd["detection"]) == {"gnss", "baro", "theta", "q"}
    assert fd["detection"]["theta"]["missed_fraction"] is None            # never injected
    assert fd["detection"]["theta"]["false_alarm_fraction"] < 0.05
    assert fd["detection"]["gnss"]["delay_s"] < 1.0                        # the 50 m step is found
    assert fd["rmse"]["f_q"]["mean"] < 0.5                                 # deg/s, about a zero truth
    assert "| f_theta | deg |" in (tmp_path / "report.md").read_text()
    y = fd["yardstick"]                    # the safety yardstick: the two injected altimeter faults
    assert y["episodes"] == 2 and y["detected"] == 2 and y["isolation"] == {"gnss": {"gnss": 1},
                                                                             "baro": {"baro": 1}}
    assert y["false_alarms_per_hour"] is not None and 0 < y["fault_free_hours"] < 20 / 3600
    assert y["delay_s"]["median"] < 1.0 and [r["p_declare"] for r in y["roc"]][0] == 0.6
    assert "## Safety yardstick" in (tmp_path / "report.md").read_text() and (tmp_path / "roc.png").exists()


@pytest.mark.parametrize("init,lo,hi", [("first_frame", 0.0, 10.0), ("trim", 150.0, 250.0)])
def test_campaign_starts_the_filter_where_the_estimator_says(ch4, init, lo, hi):
    """An estimator trimmed at 300 m over a world flying at 500 m: its first altitude estimate is the
    trim (200 m off) with init "trim", the first frame's measurement with "first_frame"."""
    import dataclasses

    from fdir_service.estimator_config import merge_documents, parse_estimator

    doc = merge_documents(ch4.estimator.doc, {"operating_point": {"altitude_m": 300.0, "init": init}})
    sc = dataclasses.replace(ch4, estimator=parse_estimator(doc, "<test>"), filters=("JMRPF",),
                             proposed="JMRPF")
    fr = run_campaign(sc, 1, particles=200, workers=1, progress=False, filters=["JMRPF"]).filters["JMRPF"]
    assert lo <= abs(fr.z_hat[0, 0, 0] - fr.z_true[0, 0, 0]) <= hi
