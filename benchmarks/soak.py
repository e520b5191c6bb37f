"""Soak (issue 7): a one-hour-equivalent lockstep run (72 000 frames at 20 Hz, `--speed 0` pace: each
frame as soon as the previous one is done) of the ch4 Aerosonde through the service's processing core
(`Pipeline`, RJMRPF N = 1000) with the flight recorder on. Prints memory growth (goal < 20 MB),
latency p50/p99 over the first and last 5 minutes of flight (goal: p99 drift <= 20 %), and frames
recorded versus sent.

    python benchmarks/soak.py [--frames 72000] [--filter RJMRPF] [--particles 1000] [--out DIR]
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fdir_service.pipeline import Pipeline  # noqa: E402
from fdir_service.recording import McapLog, Recorder  # noqa: E402
from sim_bridge.scenario import experiment_service_config, load_scenario  # noqa: E402


def rss_mb() -> float:
    """Resident set size of this process (MB), from /proc."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


@dataclass
class SoakResult:
    frames_sent: int
    frames_stepped: int
    frames_recorded: int
    rss_start_mb: float
    rss_end_mb: float
    p50_start_ms: float
    p99_start_ms: float
    p50_end_ms: float
    p99_end_ms: float
    wall_s: float
    reinitialisations: int
    rejected: dict
    cpu_p99_start_ms: float = float("nan")
    cpu_p99_end_ms: float = float("nan")

    @property
    def growth_mb(self) -> float:
        return self.rss_end_mb - self.rss_start_mb


def soak(frames: int, filter_name: str, particles: int, out_dir: Path, window: int = 6000,
         warmup: int = 400, seed: int = 0, progress: bool = False) -> SoakResult:
    """Run `frames` frames; window: frames per latency window (6000 = 5 min at 20 Hz)."""
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import SimStepper, default_autopilot

    cfg_world = load_scenario("ch4")   # the thesis ch4 world, monitored with its own estimator
    cfg = experiment_service_config(cfg_world)
    sc = cfg_world
    rec = Recorder(out_dir / "soak.mcap", rotate_bytes=int(cfg.record.rotate_mb * 1e6) or None,
                   rotate_seconds=cfg.record.rotate_s or None)
    pipe = Pipeline(cfg, filter_name=filter_name, particles=particles, seed=seed, observers=[rec])
    pipe.defer_observers(True)   # the daemon's mode: recorder encoding after the frame's output
    link = AutopilotLink(sc)
    period = sc.steps   # the scenario's flight repeats: a fresh simulator every scenario length
    st = ap = None
    window = min(window, max(frames // 4, 1))
    lat = np.empty(frames)
    cpu = np.empty(frames)   # the same in thread CPU time: insensitive to other processes' load
    rss0 = None
    t0 = time.perf_counter()
    t_ns0 = time.time_ns()
    for k in range(frames):
        if k % period == 0:
            st = SimStepper(sc, seed + k // period)
            ap = default_autopilot(sc, st.airframe)
        if k == warmup:
            gc.collect()
            rss0 = rss_mb()
        fr = st.frame()
        u = ap.update(fr.t, fr.z_true)
        t_s = k * sc.dt_s            # the autopilot's clock keeps running across repeats
        data = b"".join(link.sensor_messages(t_s, fr.y, fr.mask, fr.static_pressure_pa))
        c_in = time.thread_time()
        t_in = time.perf_counter()
        pipe.feed(data, t_ns0 + int(t_s * 1e9))
        lat[k] = time.perf_counter() - t_in     # the output is ready to send here (as in the daemon)
        cpu[k] = time.thread_time() - c_in
        pipe.drain_observers()                  # ... and the recorder encodes after it went out
        pipe.feed(b"".join(link.actuator_messages(t_s, u)), t_ns0 + int(t_s * 1e9))
        pipe.drain_observers()
        st.advance(u)
        if progress and k and k % 6000 == 0:
            print(f"  {k} frames, {rss_mb():.1f} MB, {time.perf_counter() - t0:.0f} s", flush=True)
    pipe.close(t_ns0 + int(frames * sc.dt_s * 1e9))
    pipe.drain_observers()
    rec.close()
    gc.collect()
    rss1 = rss_mb()
    wall = time.perf_counter() - t0
    recorded = sum(sum(1 for _ in McapLog(p).iter_messages("/fdir/estimate")) for p in rec.paths)
    a = lat[warmup:warmup + window] * 1e3
    b = lat[-window:] * 1e3
    ca, cb = cpu[warmup:warmup + window] * 1e3, cpu[-window:] * 1e3
    return SoakResult(frames, pipe.frames, recorded, rss0 if rss0 is not None else rss1, rss1,
                      float(np.percentile(a, 50)), float(np.percentile(a, 99)),
                      float(np.percentile(b, 50)), float(np.percentile(b, 99)), wall,
                      pipe.reinitialisations, pipe.rejected_counts,
                      float(np.percentile(ca, 99)), float(np.percentile(cb, 99)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=72_000)
    ap.add_argument("--filter", default="RJMRPF")
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--out", type=Path, default=None, help="keep the recording here (default: a temp dir)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        r = soak(args.frames, args.filter, args.particles, out, progress=True)
    drift = (r.p99_end_ms / r.p99_start_ms - 1.0) * 100.0
    print(f"soak: {args.filter} N={args.particles}, {r.frames_sent} frames sent "
          f"({r.frames_sent / 20 / 60:.1f} min of flight) in {r.wall_s:.0f} s wall")
    print(f"memory: {r.rss_start_mb:.1f} MB -> {r.rss_end_mb:.1f} MB, growth {r.growth_mb:+.1f} MB "
          "(goal < 20)")
    print(f"latency first 5 min: p50 {r.p50_start_ms:.2f} ms, p99 {r.p99_start_ms:.2f} ms; "
          f"last 5 min: p50 {r.p50_end_ms:.2f} ms, p99 {r.p99_end_ms:.2f} ms; p99 drift {drift:+.0f} % "
          "(goal within 20 %)")
    cdrift = (r.cpu_p99_end_ms / r.cpu_p99_start_ms - 1) * 100
    print(f"CPU time per feed (not affected by other processes): p99 {r.cpu_p99_start_ms:.2f} ms "
          f"first 5 min, {r.cpu_p99_end_ms:.2f} ms last 5 min ({cdrift:+.0f} %)")
    print(f"frames: sent {r.frames_sent}, stepped {r.frames_stepped}, recorded {r.frames_recorded}; "
          f"re-initialisations {r.reinitialisations}; rejected {r.rejected or 'none'}")
    return 0 if r.frames_recorded == r.frames_sent else 1


if __name__ == "__main__":
    sys.exit(main())
