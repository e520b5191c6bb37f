"""Replay speed: how many times faster than real time `fdir replay` runs a recorded flight.

Flies ch4 in sim-bridge's simulator for --seconds (default 50 s), feeds the autopilot's MAVLink
bytes through a Pipeline with a Recorder (the "flight"), then times `fdir_service.replay.replay`
on that log (also with --out, i.e. re-recording). Goal (issue 6): a 50 s log at N = 1000 replays
at least 50x faster than real time. Prints the figures; asserts nothing.

    .venv/bin/python benchmarks/replay_speed.py [--filter JMRPF] [--particles 1000] [--seconds 50]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fdir_service.pipeline import Pipeline
from fdir_service.recording import Recorder
from fdir_service.replay import replay
from sim_bridge.scenario import experiment_service_config, load_scenario


def record_flight(path: Path, filter_name: str, particles: int, seconds: float, seed: int) -> float:
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import run

    cfg_world = load_scenario("ch4")   # the thesis ch4 world, monitored with its own estimator
    cfg = experiment_service_config(cfg_world)
    traj = run(cfg_world, seed=seed, seconds=seconds)
    link = AutopilotLink(cfg_world)
    t0 = time.perf_counter()
    with Recorder(path) as rec:
        pipe = Pipeline(cfg, filter_name=filter_name, particles=particles, seed=seed, observers=[rec])
        for k in range(len(traj.t)):
            data = b"".join(link.sensor_messages(traj.t[k], traj.y[k], traj.mask[k],
                                                 traj.static_pressure_pa[k]))
            data += b"".join(link.actuator_messages(traj.t[k], traj.u[k]))
            pipe.feed(data, int(traj.t[k] * 1e9))
        pipe.close(int(traj.t[-1] * 1e9))
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--filter", default="JMRPF")
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=50.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=3, help="replays to time (best is reported)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        log = Path(d) / "flight.mcap"
        rec_s = record_flight(log, args.filter, args.particles, args.seconds, args.seed)
        size = log.stat().st_size
        print(f"flight: ch4 {args.seconds:.0f} s, {args.filter} N={args.particles}; live pipeline + recorder "
              f"{rec_s:.2f} s ({args.seconds / rec_s:.0f}x real time); log {size / 1e6:.2f} MB")
        best = None
        for _ in range(args.repeat):
            r = replay(log)
            best = r if best is None or r.wall_s < best.wall_s else best
        assert best is not None
        print(f"replay:            {best.frames} frames in {best.wall_s:.3f} s = {best.speed:.0f}x real time "
              f"({1e3 * best.wall_s / best.frames:.3f} ms/frame); {best.identity.describe()}")
        r = replay(log, out=Path(d) / "again.mcap")
        print(f"replay --out:      {r.frames} frames in {r.wall_s:.3f} s = {r.speed:.0f}x real time")
        goal = "met" if best.speed >= 50 else "NOT met"
        print(f"goal (>= 50x at N = 1000 over a 50 s log): {goal}")


if __name__ == "__main__":
    main()
