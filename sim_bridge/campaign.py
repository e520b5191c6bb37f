"""Monte Carlo campaigns (thesis [D], SPEC sections 7-8): independent closed-loop runs of every
filter of a scenario, in parallel worker processes or on a dask.distributed cluster.

A *job* is one (scenario, filter, run index): `sim_bridge.simulate.run` flies the scenario with the
autopilot on that filter's own estimate (nav = filter.step), as in the thesis, unless the scenario's
navigation is "onboard" or "truth" (`onboard_nav`: the filter then only watches). Seeds come from
`SeedSequence(seed)`: run r's simulator seed depends only on (seed, r), so the sensor noise of run
r is the same for every filter; each filter's own random stream depends on (seed, r, filter name),
so adding a filter changes nobody else's numbers.

A job returns a small `RunResult` (float32 arrays, ~100 kB): per-step state and fault estimates,
fault probabilities, the truth, Pfa/Pmd/transition matrices of adaptive filters, and the 20 most
weighted particles at every whole second.
"""

from __future__ import annotations

import os
import sys
import time
import zlib
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from sim_bridge.scenario import Scenario

GATE = "EKF-GATE"
TOP_K = 20


def campaign_filters(scenario: Scenario) -> tuple[str, ...]:
    """The filters a campaign runs: the experiment's (experiment.filters) plus the EKF-GATE baseline."""
    f = tuple(scenario.filters)
    return f if GATE in f else f + (GATE,)


def sim_seed(seed: int, run: int) -> int:
    """The simulator seed of run `run` (same for every filter: common sensor noise)."""
    ss = np.random.SeedSequence(seed, spawn_key=(run, 0))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def filter_rng(seed: int, run: int, name: str) -> np.random.Generator:
    """The filter's own generator for run `run`, keyed by its name (stable when filters are added)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, 1, zlib.crc32(name.encode()))))


def build(name: str, scenario: Scenario, rng: np.random.Generator, particles: int | None = None,
          x0: np.ndarray | None = None):
    """Any filter of the project by name (fdir_service.estimation.recipes) for the experiment's
    estimator; x0 (5,): its initial airframe state (default: the estimator's trim)."""
    from fdir_service.estimation.factory import build_filter
    return build_filter(name, scenario.estimator, rng, particles=particles, x0=x0)


def simulate(scenario: Scenario, seed: int, nav=None):
    """The closed-loop simulator (sim_bridge.simulate.run)."""
    from sim_bridge.simulate import run
    return run(scenario, seed, nav=nav)


@dataclass(frozen=True)
class Job:
    """One closed-loop run. `builder(name, scenario, rng, particles)` and `simulator(scenario,
    seed, nav)` default to the project's; tests hand in small fakes (module-level functions)."""

    scenario: Scenario
    filter: str
    run: int
    seed: int
    particles: int | None = None
    builder: Callable | None = None
    simulator: Callable | None = None


@dataclass
class RunResult:
    """What one run keeps. K steps, nf faults, n extended-state size, S whole seconds.

    t (K,) s; z_true (K, 5), z_hat (K, 5) SI; f_true, f_hat, prob (K, nf) SI / P(mode 1);
    pfa, pmd (K, nf) and transition (K, nf, 2, 2) or None; n_eff (K,);
    top_t (S,), top_x (S, 20, n), top_w (S, 20): the most weighted particles each second (NaN pad);
    filter_s: time spent in the filter's steps, wall_s: the whole run (s).
    """

    filter: str
    run: int
    sim_seed: int
    t: np.ndarray
    z_true: np.ndarray
    z_hat: np.ndarray
    f_true: np.ndarray
    f_hat: np.ndarray
    prob: np.ndarray
    n_eff: np.ndarray
    top_t: np.ndarray
    top_x: np.ndarray
    top_w: np.ndarray
    pfa: np.ndarray | None = None
    pmd: np.ndarray | None = None
    transition: np.ndarray | None = None
    filter_s: float = 0.0
    wall_s: float = 0.0
    world_faults: np.ndarray | None = None
    """(K, nw) the world's own injected faults (SI, its fault order), monitored or not: the
    additive-equivalent truth (`fault_types`)."""
    world_active: np.ndarray | None = None
    """(K, nw) bool: each world fault active (`fault_types.activity`)."""


class _TimedNav:
    """Wraps filter.step: maps the world's sensor rows onto the estimator's (`rows` (m_est,), -1:
    never arrives), times the step and snapshots the top particles at every whole second.
    start(y, mask) -> filter: with operating_point.init = "first_frame", the filter the first frame
    starts (on its measurements), as the service does."""

    def __init__(self, filt, dt: float, rows: np.ndarray, start=None, world_rows: int | None = None) -> None:
        self.filt = filt
        self.start = start
        same = np.array_equal(rows, np.arange(rows.size)) and world_rows in (None, rows.size)
        self.rows = None if same else rows
        self.every = max(1, int(round(1.0 / dt)))
        self.k = 0
        self.seconds = 0.0
        self.top: list[tuple[float, np.ndarray, np.ndarray]] = []

    def __call__(self, t, y, mask, u):
        if self.rows is not None:
            y, mask = y[self.rows], mask[self.rows] & (self.rows >= 0)
        if self.k == 0 and self.start is not None:
            self.filt = self.start(y, mask)
        t0 = time.perf_counter()
        out = self.filt.step(t, y, mask, u)
        self.seconds += time.perf_counter() - t0
        if self.k % self.every == 0:
            x, w = self.filt.top_particles(TOP_K)
            self.top.append((t, np.asarray(x, float), np.asarray(w, float)))
        self.k += 1
        return out


def _stack_opt(outputs: list, attr: str) -> np.ndarray | None:
    vals = [getattr(o, attr, None) for o in outputs]
    if any(v is None for v in vals):
        return None
    return np.asarray(vals, dtype=np.float32)


@dataclass
class RunFailure:
    """A job that raised: kept (and reported) instead of sinking the whole campaign."""

    filter: str
    run: int
    sim_seed: int
    error: str


def run_job(job: Job) -> RunResult | RunFailure:
    """Run one job (in whichever process it lands) on one BLAS thread; an exception becomes a
    RunFailure. One thread: the campaign's parallelism is its processes. Two workers whose BLAS
    thread pools each spread a (25 x 1000) product over both cores of a 2-core machine spun against
    each other: a real-drift campaign ran at 87 ms per filter step instead of 2.2."""
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            return _run_job(job)
    except Exception as exc:  # noqa: BLE001 - reported in results.json and on stderr
        import traceback
        frames = traceback.extract_tb(exc.__traceback__)
        ours = [f for f in frames if "/fdir_service/" in f.filename or "/sim_bridge/" in f.filename]
        tb = (ours or frames)[-1]
        return RunFailure(job.filter, job.run, sim_seed(job.seed, job.run),
                          f"{type(exc).__name__}: {exc} ({tb.filename.split('/')[-1]}:{tb.lineno})")


def _first_frame_start(sc: Scenario, new_filter):
    """For operating_point.init = "first_frame": y, mask -> the filter started on the state made
    from the first frame (`measurement.measured_state` about the trim); else None."""
    if sc.estimator.operating_point.init != "first_frame":
        return None
    from fdir_service.estimation.factory import trim_state
    from fdir_service.estimation.measurement import measured_state

    trim = trim_state(sc.estimator)
    return lambda y, mask: new_filter(measured_state(sc.estimator.measurements, y, mask, trim))


def fly(scenario: Scenario, name: str, run: int, seed: int = 0, seconds: float | None = None,
        particles: int | None = None):
    """Run `run` of a campaign (same world and filter streams) flown once with filter `name` as its
    navigation, on one BLAS thread as `run_job`: the `simulate.Trajectory`, whose `outputs` are the
    filter's StepOutputs."""
    def new_filter(x0=None):
        kw = {} if x0 is None else {"x0": x0}
        return build(name, scenario, filter_rng(seed, run, name), particles, **kw)

    nav = _TimedNav(new_filter(), scenario.dt_s, scenario.estimator_rows(),
                    _first_frame_start(scenario, new_filter), len(scenario.sensors.measurements))
    from sim_bridge.simulate import run as fly_closed_loop
    with threadpool_limits(limits=1, user_api="blas"):
        return fly_closed_loop(scenario, sim_seed(seed, run), seconds=seconds, nav=nav)


def _run_job(job: Job) -> RunResult:
    t_start = time.perf_counter()
    sc = job.scenario
    builder = job.builder or build
    simulator = job.simulator or simulate
    seed = sim_seed(job.seed, job.run)
    def new_filter(x0=None):
        kw = {} if x0 is None else {"x0": x0}
        filt = builder(job.filter, sc, filter_rng(job.seed, job.run, job.filter), job.particles, **kw)
        if hasattr(filt, "output_covariance"):   # a RunResult keeps no covariance: skip computing it
            filt.output_covariance = False
        return filt

    nav = _TimedNav(new_filter(), sc.dt_s, sc.estimator_rows(), _first_frame_start(sc, new_filter),
                    len(sc.sensors.measurements))
    traj = simulator(sc, seed, nav=nav)
    outs = traj.outputs
    n = len(outs[0].x_mean)
    S = len(nav.top)
    top_x = np.full((S, TOP_K, n), np.nan, dtype=np.float32)
    top_w = np.full((S, TOP_K), np.nan, dtype=np.float32)
    for s, (_, x, w) in enumerate(nav.top):
        kk = min(len(w), TOP_K)
        top_x[s, :kk] = x[:kk]
        top_w[s, :kk] = w[:kk]
    f32 = np.float32
    return RunResult(
        filter=job.filter, run=job.run, sim_seed=seed,
        t=np.asarray(traj.t, float),
        z_true=np.asarray(traj.z, f32),
        z_hat=np.asarray([o.x_mean[:5] for o in outs], f32),
        f_true=sc.estimator_fault_truth(np.asarray(traj.faults, f32).reshape(len(outs), -1)),
        f_hat=np.asarray([o.fault_estimate for o in outs], f32).reshape(len(outs), -1),
        prob=np.asarray([o.fault_probability for o in outs], f32).reshape(len(outs), -1),
        n_eff=np.asarray([o.n_eff for o in outs], f32),
        top_t=np.asarray([tt for tt, _, _ in nav.top], float),
        top_x=top_x, top_w=top_w,
        pfa=_stack_opt(outs, "pfa"), pmd=_stack_opt(outs, "pmd"),
        transition=_stack_opt(outs, "transition"),
        filter_s=nav.seconds, wall_s=time.perf_counter() - t_start,
        world_faults=np.asarray(traj.faults, f32).reshape(len(outs), -1),
        world_active=None if traj.active is None else np.asarray(traj.active, bool).reshape(len(outs), -1),
    )


def make_jobs(scenario: Scenario, runs: int, seed: int = 0, particles: int | None = None,
              filters: Iterable[str] | None = None, builder: Callable | None = None,
              simulator: Callable | None = None) -> list[Job]:
    """All jobs of a campaign, run-major (run 0 of every filter first) so progress is even."""
    names = tuple(filters) if filters is not None else campaign_filters(scenario)
    return [Job(scenario, name, r, seed, particles, builder, simulator)
            for r in range(runs) for name in names]


@dataclass
class FilterRuns:
    """Every run of one filter, stacked: arrays of RunResult with a leading run axis R."""

    filter: str
    t: np.ndarray
    z_true: np.ndarray
    z_hat: np.ndarray
    f_true: np.ndarray
    f_hat: np.ndarray
    prob: np.ndarray
    n_eff: np.ndarray
    top_t: np.ndarray
    top_x: np.ndarray
    top_w: np.ndarray
    pfa: np.ndarray | None
    pmd: np.ndarray | None
    transition: np.ndarray | None
    filter_s: np.ndarray
    wall_s: np.ndarray
    sim_seeds: np.ndarray
    failures: list[RunFailure] = field(default_factory=list)
    world_faults: np.ndarray | None = None
    """(R, K, nw) the world's injected faults per run."""
    world_active: np.ndarray | None = None
    """(R, K, nw) bool: each world fault active per run (False in a failed run)."""

    def fault_active(self, scenario: Scenario) -> np.ndarray:
        """(R, K, nf) bool: each monitored fault's world fault active (by id; `f_true != 0` when
        the runs kept no activity)."""
        if self.world_active is None:
            return self.f_true != 0.0
        return scenario.estimator_fault_truth(self.world_active)


@dataclass
class Campaign:
    """A finished campaign: per filter, its stacked runs; plus how it was run."""

    scenario: Scenario
    runs: int
    particles: int
    seed: int
    filters: dict[str, FilterRuns] = field(default_factory=dict)
    wall_s: float = 0.0


def stack_runs(results: list[RunResult | RunFailure]) -> FilterRuns:
    """Stack one filter's results in run order; a failed run's rows are NaN (RMSE skips them)."""
    done = sorted((r for r in results if isinstance(r, RunResult)), key=lambda r: r.run)
    failures = sorted((r for r in results if isinstance(r, RunFailure)), key=lambda r: r.run)
    if not done:
        raise RuntimeError(f"every run of {failures[0].filter} failed, e.g. run {failures[0].run}: "
                           f"{failures[0].error}")
    ref = done[0]
    rs = []
    for r in sorted(results, key=lambda r: r.run):
        if isinstance(r, RunFailure):
            nan = {a: (None if getattr(ref, a) is None else np.full_like(getattr(ref, a), np.nan))
                   for a in ("z_true", "z_hat", "f_true", "f_hat", "prob", "n_eff", "top_x", "top_w",
                             "pfa", "pmd", "transition", "world_faults")}
            r = RunResult(r.filter, r.run, r.sim_seed, ref.t, top_t=ref.top_t, filter_s=np.nan,
                          wall_s=np.nan, **nan,
                          world_active=None if ref.world_active is None else np.zeros_like(ref.world_active))
        rs.append(r)

    def st(attr):
        vals = [getattr(r, attr) for r in rs]
        return None if any(v is None for v in vals) else np.stack(vals)

    return FilterRuns(
        filter=rs[0].filter, t=rs[0].t, z_true=st("z_true"), z_hat=st("z_hat"), f_true=st("f_true"),
        f_hat=st("f_hat"), prob=st("prob"), n_eff=st("n_eff"), top_t=rs[0].top_t, top_x=st("top_x"),
        top_w=st("top_w"), pfa=st("pfa"), pmd=st("pmd"), transition=st("transition"),
        filter_s=np.array([r.filter_s for r in rs]), wall_s=np.array([r.wall_s for r in rs]),
        sim_seeds=np.array([r.sim_seed for r in rs]), failures=failures, world_faults=st("world_faults"),
        world_active=st("world_active"),
    )


def _preload(jobs: list[Job]) -> None:
    """Import the simulator and the filters and fill the per-process design caches (trim, linear
    model, autopilot gains) here, before the pool forks: every worker then starts warm instead of
    paying ~2 s of imports and designs on its first job. Best effort: a failure shows up in the job."""
    try:
        if any(j.builder is None for j in jobs):
            import fdir_service.estimation.factory  # noqa: F401
            import fdir_service.estimation.gating  # noqa: F401
        if any(j.simulator is None for j in jobs):
            from sim_bridge.simulate import SimStepper, default_autopilot
            for sc in {id(j.scenario): j.scenario for j in jobs}.values():
                stepper = SimStepper(sc, 0)
                default_autopilot(sc, stepper.airframe)
    except Exception:  # noqa: BLE001 - the jobs themselves report any real problem
        pass


def _local(jobs: list[Job], workers: int) -> Iterator[RunResult | RunFailure]:
    if workers <= 1:
        for job in jobs:
            yield run_job(job)
        return
    _preload(jobs)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(run_job, job) for job in jobs]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        except BaseException:
            for fut in futures:
                fut.cancel()
            raise


def _dask(jobs: list[Job], address) -> Iterator[RunResult | RunFailure]:
    from distributed import Client
    from distributed import as_completed as dask_completed

    own = not isinstance(address, Client)
    client = Client(address) if own else address
    try:
        futures = client.map(run_job, jobs, pure=False)
        for fut in dask_completed(futures):
            yield fut.result()
    finally:
        if own:
            client.close()


def run_campaign(scenario: Scenario, runs: int, particles: int | None = None, seed: int = 0,
                 workers: int | None = None, dask=None, progress: bool = True,
                 filters: Iterable[str] | None = None, builder: Callable | None = None,
                 simulator: Callable | None = None) -> Campaign:
    """Run every (filter, run) of a scenario and stack the results per filter.

    workers: local processes (default: the core count; 1 runs in this process); dask: a scheduler
    address (or a `distributed.Client`) to send the jobs to instead. progress: a tqdm bar on stderr
    with runs done and time left.
    """
    from tqdm import tqdm

    t0 = time.perf_counter()
    jobs = make_jobs(scenario, runs, seed, particles, filters, builder, simulator)
    if workers is None:
        workers = os.cpu_count() or 1
    source = _dask(jobs, dask) if dask is not None else _local(jobs, workers)
    by_filter: dict[str, list[RunResult | RunFailure]] = {}
    with tqdm(total=len(jobs), unit="run", desc=scenario.id, disable=not progress,
              dynamic_ncols=True) as bar:
        for res in source:
            by_filter.setdefault(res.filter, []).append(res)
            if isinstance(res, RunFailure):
                bar.write(f"{scenario.id} {res.filter} run {res.run} failed: {res.error}", file=sys.stderr)
            bar.update(1)
    names = [n for n in dict.fromkeys(j.filter for j in jobs)]
    camp = Campaign(scenario, runs, particles or scenario.estimator.particles, seed)
    for name in names:
        camp.filters[name] = stack_runs(by_filter[name])
    camp.wall_s = time.perf_counter() - t0
    return camp
