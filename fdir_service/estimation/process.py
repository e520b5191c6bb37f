"""Process models on the extended state x = [z, f], state-major clouds X (n, N) (SPEC section 5).

Fault entries follow a zero-order (random-walk) model: the deterministic step leaves them as they
are; process noise is added by the filter. An actuator fault f_j adds to its input, so the
airframe sees u_eff = u + G f (G from the fault layout), exactly like the input itself.

- `LinearProcess`: z_{k+1} = z* + F (z - z*) + B (u_eff - u*) with a `LinearModel` (F, B about
  trim), as one (n, n) matrix product plus a constant: X <- F_ext X + c(u).
- `NonlinearProcess`: the airframe's `derivatives_rows` integrated over dt by the integrator
  chosen in `INTEGRATORS`. The default is "expeuler": x+ = x + Phi f(x, u_eff) with
  Phi = int_0^dt e^{A s} ds for the trim Jacobian A (one right-hand-side evaluation per step,
  exact for the linearised dynamics; see docs/estimation.md for the accuracy/cost table).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from fdir_service.airframe.dynamics import SCRATCH_ROWS, derivatives_block_into, derivatives_rows
from fdir_service.airframe.linearize import LinearModel, jacobians
from fdir_service.airframe.params import AirframeParams
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout

INTEGRATORS = ("expeuler", "euler", "heun", "rk4")


def _row_input(a, N: int) -> bool:
    """An input `derivatives_block_into` takes as it is: a float, or a 0-d or (N,) array."""
    return type(a) is float or getattr(a, "shape", None) in ((), (N,))


class WholeFrameStep:
    """A process model whose propagate is the whole frame: nothing to close after the correction
    (`KinematicProcess.close_frame` is the one that has something)."""

    def close_frame(self, prior: np.ndarray, X: np.ndarray, rng: np.random.Generator | None = None,
                    frame=None) -> None:
        """Nothing: X (n, N) after the frame's correction stays as it is."""


class LinearProcess(WholeFrameStep):
    """Linear discrete model about trim on the extended state (faults: random walk)."""

    kind = "linear"

    def __init__(self, model: LinearModel, layout: FaultLayout) -> None:
        n, nf = layout.n, layout.nf
        self.model = model
        self.layout = layout
        self.dt = model.dt
        G = layout.input_matrix()                     # (2, nf)
        F_ext = np.eye(n)
        F_ext[:N_AIRFRAME, :N_AIRFRAME] = model.F
        F_ext[:N_AIRFRAME, N_AIRFRAME:] = model.B @ G
        self.F = F_ext                                # (n, n)
        self.B = np.zeros((n, 2))                     # (n, 2) input matrix on the extended state
        self.B[:N_AIRFRAME] = model.B
        c0 = np.zeros(n)                              # constant part: (I - F) z* - B u*
        c0[:N_AIRFRAME] = model.trim.z - model.F @ model.trim.z - model.B @ model.trim.u
        self._c0 = c0
        self.B_actuator = model.B @ G                 # (5, nf) airframe response to each fault entry
        self.nf = nf

    def offset(self, u: np.ndarray) -> np.ndarray:
        """Constant term c(u) (n,) of x_{k+1} = F x_k + c(u)."""
        return self._c0 + self.B @ np.asarray(u, dtype=float)

    def propagate(self, X: np.ndarray, u: np.ndarray, modes: np.ndarray | None = None) -> np.ndarray:
        """Deterministic step of a cloud X (n, N) (or one state (n,)) with input u (2,); modes: the
        cloud's fault modes, which this model does not use."""
        c = self.offset(u)
        if X.ndim == 1:
            return self.F @ X + c
        out = self.F @ X
        out += c[:, None]
        return out


_DISCRETISED: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def _discretised(params: AirframeParams, trim_z: np.ndarray, trim_u: np.ndarray,
                 dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Bc (5, 2), E (10, 10)) at the trim: the input Jacobian and the augmented exponential
    E = expm([[A dt, I dt], [0, 0]]), whose block E[:5, 5:] = Phi = int_0^dt e^{A s} ds.

    Computed once per (airframe, trim, dt) in a process (~9 ms: a campaign builds three particle
    filters per run); the arrays are shared read-only.
    """
    try:
        key = (params, trim_z.tobytes(), trim_u.tobytes(), float(dt))
        hit = _DISCRETISED.get(key)
    except TypeError:       # an unhashable parameter set: no caching
        key, hit = None, None
    if hit is not None:
        return hit
    A, Bc = jacobians(params, trim_z, trim_u)
    M = np.zeros((10, 10))
    M[:5, :5] = A * dt
    M[:5, 5:] = np.eye(5) * dt
    E = expm(M)
    Bc.flags.writeable = False
    E.flags.writeable = False
    if key is not None:
        if len(_DISCRETISED) > 32:
            _DISCRETISED.clear()
        _DISCRETISED[key] = (Bc, E)
    return Bc, E


class NonlinearProcess(WholeFrameStep):
    """The nonlinear airframe (SPEC section 2) over one frame dt, vectorised over particles."""

    kind = "nonlinear"

    def __init__(self, params: AirframeParams, trim_z: np.ndarray, trim_u: np.ndarray, dt: float,
                 layout: FaultLayout, integrator: str = "expeuler") -> None:
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
        self.params = params
        self.dt = float(dt)
        self.layout = layout
        self.integrator = integrator
        self.G = layout.input_matrix()                # (2, nf)
        self._act = [(i, np.flatnonzero(self.G[i])) for i in range(2) if self.G[i].any()]
        Bc, E = _discretised(params, np.asarray(trim_z, float), np.asarray(trim_u, float), dt)
        self.Phi = E[:5, 5:]                          # (5, 5)
        self.B_actuator = self.Phi @ Bc @ self.G      # (5, nf) one-frame response to each fault entry
        self._scratch = np.empty((SCRATCH_ROWS, 0))   # derivatives_block_into's work rows

    def _inputs(self, X: np.ndarray, u: np.ndarray) -> tuple:
        """delta_e, delta_t seen by each particle (scalars or (N,) rows): u + G f."""
        de, dt = float(u[0]), float(u[1])
        eff = [de, dt]
        for i, cols in self._act:
            add = X[N_AIRFRAME + cols[0]]
            for c in cols[1:]:
                add = add + X[N_AIRFRAME + c]
            eff[i] = eff[i] + add
        return eff[0], eff[1]

    def _rhs(self, Z: np.ndarray, de, dtl) -> np.ndarray:
        out = np.empty(Z.shape)
        N = Z.shape[1]
        if Z.dtype == np.float64 and _row_input(de, N) and _row_input(dtl, N):
            # same arithmetic as derivatives_rows, without its temporaries (bit-identical)
            if self._scratch.shape[1] != N:
                self._scratch = np.empty((SCRATCH_ROWS, N))
            return derivatives_block_into(out, self._scratch, Z, de, dtl, self.params)
        d = derivatives_rows(Z[1], Z[2], Z[3], Z[4], de, dtl, self.params)
        for i, r in enumerate(d):
            out[i] = r
        return out

    def propagate(self, X: np.ndarray, u: np.ndarray, modes: np.ndarray | None = None) -> np.ndarray:
        """Deterministic step of a cloud X (n, N) (or one state (n,)) with input u (2,) held over dt;
        modes: the cloud's fault modes, which this model does not use."""
        one = X.ndim == 1
        if one:
            X = X[:, None]
        de, dtl = self._inputs(X, u)
        Z = X[:N_AIRFRAME]
        h = self.dt
        if self.integrator == "expeuler":
            out = np.empty_like(X)
            np.add(Z, self.Phi @ self._rhs(Z, de, dtl), out=out[:N_AIRFRAME])
            out[N_AIRFRAME:] = X[N_AIRFRAME:]
            return out[:, 0] if one else out
        elif self.integrator == "euler":
            Zn = Z + h * self._rhs(Z, de, dtl)
        elif self.integrator == "heun":
            k1 = self._rhs(Z, de, dtl)
            k2 = self._rhs(Z + h * k1, de, dtl)
            Zn = Z + (0.5 * h) * (k1 + k2)
        else:
            k1 = self._rhs(Z, de, dtl)
            k2 = self._rhs(Z + (0.5 * h) * k1, de, dtl)
            k3 = self._rhs(Z + (0.5 * h) * k2, de, dtl)
            k4 = self._rhs(Z + h * k3, de, dtl)
            Zn = Z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out = np.empty_like(X)
        out[:N_AIRFRAME] = Zn
        out[N_AIRFRAME:] = X[N_AIRFRAME:]
        return out[:, 0] if one else out
