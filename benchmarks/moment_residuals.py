"""How far the pitching moment's one-frame prediction of the pitch rate misses the gyro, on a
world's fault-free flight: what `parts.q_noise = "learned"` learns (docs/faults.md, "The pitch-rate
noise the flight shows").

    python benchmarks/moment_residuals.py real-catalogue-faultfree [--seed 4] [--seconds 120]

Flies the world (its faults removed, the autopilot on the true state: no filter runs) and prints
the rms of the gyro's frame-to-frame change and of the residual

    e_k = y_k - y_k-1 - dt q'(y_k-1, delta_e, a_z, V)

with the moment's inputs paired three ways: the elevator commanded over the frame with the
accelerometer and airspeed read at its end (parts.az_input = "frame_end"), all read at its start,
and the accelerometer averaged over the frame ("frame_mean", the catalogue's). deg/s per frame.
Then the body-z velocity's one-frame residual on the true state, w_k - w_k-1 - dt (a_z + q u +
g cos(theta)) (m/s per frame), with a_z paired both ways.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from fdir_service.airframe import load_airframe
from fdir_service.estimation.inputs import G
from fdir_service.estimation.kinematic import PitchMoment
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=120.0)
    a = ap.parse_args()
    sc = dataclasses.replace(load_scenario(a.world), faults=())
    tr = run(sc, a.seed, seconds=a.seconds)
    rows = list(sc.sensors.measurements)
    moment = PitchMoment(load_airframe(sc.estimator.airframe))
    y, az, V = (tr.y[:, rows.index(r)] for r in ("q", "az", "airspeed"))
    de, dt = tr.u[:, 0], sc.dt_s                 # u_k: the command from frame k, flown over k -> k+1
    step = y[1:] - y[:-1]

    def rms(de_, az_, V_) -> float:
        return float(np.degrees((step - dt * moment.qdot(y[:-1], de_, az_, V_)).std()))

    print(f"{a.world}, seed {a.seed}, {a.seconds:g} s; deg/s per frame")
    print(f"  gyro frame-to-frame change          {np.degrees(step.std()):.3f}")
    print(f"  residual, az_input = frame_end      {rms(de[:-1], az[1:], V[1:]):.3f}")
    print(f"  residual, inputs at the frame start {rms(de[:-1], az[:-1], V[:-1]):.3f}")
    print(f"  residual, az_input = frame_mean     {rms(de[:-1], 0.5 * (az[1:] + az[:-1]), V[1:]):.3f}")
    print(f"  configured sigma_x[4] per frame     "
          f"{np.degrees(sc.estimator.settings.sigma_x[4] * np.sqrt(dt)):.3f}")
    _, u, w, theta, q = tr.z.T
    mid = theta[:-1] + 0.5 * dt * q[:-1]
    for name, a in (("frame_end ", az[1:]), ("frame_mean", 0.5 * (az[1:] + az[:-1]))):
        r = w[1:] - w[:-1] - dt * (a + q[:-1] * u[:-1] + G * np.cos(mid))
        print(f"  w residual (m/s), az_input = {name} {r.std():.4f}")
    print(f"  configured sigma_x[2] per frame     {sc.estimator.settings.sigma_x[2] * np.sqrt(dt):.4f}")


if __name__ == "__main__":
    main()
