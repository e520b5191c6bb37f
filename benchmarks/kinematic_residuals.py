"""How well the kinematic model's equations hold on a world's true state: the mean and rms residual
of each, and the rms of its 10 s integral, how far the state would drift in 10 s with nothing to
correct it (docs/robustness.md, "Banks and sideslip", "Body rates").

    python benchmarks/kinematic_residuals.py real-jsbsim-faultfree [--seed 1] [--seconds 120]

Flies the world on its true state and compares central differences of the truth with the
equations of `fdir_service.estimation.kinematic`, longitudinal and with the lateral terms (roll
phi, body-y velocity v, roll and yaw rates p, r; JSBSim only: the internal aircraft is wings level).
"""

from __future__ import annotations

import argparse

import numpy as np

from fdir_service.estimation.inputs import G
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run

LATERAL = ("attitude/phi-rad", "velocities/v-fps", "velocities/p-rad_sec", "velocities/r-rad_sec")


def _record_lateral(record: list) -> None:
    """Make JSBSim's truth append [phi, v, p, r] (SI) to `record` at every frame."""
    import sim_bridge.jsbsim_truth as J

    read = J.JSBSimTruth._read_z

    def read_z(self):
        z = read(self)
        phi, v_fps, p, r = (self.fdm[name] for name in LATERAL)
        record.append([phi, v_fps * J.FT, p, r])
        return z

    J.JSBSimTruth._read_z = read_z


def residuals(world: str, seed: int, seconds: float) -> dict[str, np.ndarray]:
    """{equation: residual (K - 2,)} on the world's true state."""
    sc = load_scenario(world)
    record: list = []
    if sc.sky.engine == "jsbsim":
        _record_lateral(record)
    tr = run(sc, seed, seconds=seconds)
    K = len(tr.t)
    phi, v, p, r = np.array(record[-K:]).T if record else np.zeros((4, K))
    rows = list(sc.sensors.measurements)
    ax, az = tr.y[:, rows.index("ax")], tr.y[:, rows.index("az")]
    pd, u, w, th, q = tr.z.T
    d = lambda x: (x[2:] - x[:-2]) / (tr.t[2] - tr.t[0])          # noqa: E731 - central difference
    m = slice(1, -1)
    s, c = np.sin(th[m]), np.cos(th[m])
    tilted = v[m] * np.sin(phi[m]) + w[m] * np.cos(phi[m])
    return {
        "h', longitudinal": -d(pd) - (u[m] * s - w[m] * c),
        "h', with phi and v": -d(pd) - (u[m] * s - tilted * c),
        "theta' = q": d(th) - q[m],
        "theta' = q cos(phi) - r sin(phi)": d(th) - (q[m] * np.cos(phi[m]) - r[m] * np.sin(phi[m])),
        "u', longitudinal": d(u) - (ax[m] - q[m] * w[m] - G * s),
        "u', with r v": d(u) - (ax[m] - q[m] * w[m] + r[m] * v[m] - G * s),
        "w', longitudinal": d(w) - (az[m] + q[m] * u[m] + G * c),
        "w', with cos(phi) and - p v": d(w) - (az[m] + q[m] * u[m] - p[m] * v[m] + G * c * np.cos(phi[m])),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=120.0)
    a = ap.parse_args()
    sc = load_scenario(a.world)
    ten_s = np.ones(int(round(10.0 / sc.dt_s)))
    for name, res in residuals(a.world, a.seed, a.seconds).items():
        drift = np.convolve(res, ten_s, "valid") * sc.dt_s
        print(f"{name:36s} mean {res.mean():+.4f}  rms {res.std():.4f}  10 s drift rms {drift.std():.4f}")


if __name__ == "__main__":
    main()
