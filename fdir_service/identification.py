"""`fdir identify`: the longitudinal airframe fitted to a fault-free flight recorded by the service.

What the robust monitor needs of its airframe is the pitch balance of `kinematic.PitchMoment`:

    q' / K(V) = C_m0 + C_ma alpha + C_mq c q / (2 V) + C_mde delta_e,   K = qbar S c / J_y,
    C_L       = -a_z m / (qbar S) = C_L0 + C_La alpha + C_Lde delta_e   (linear below stall),

with V the pitot's airspeed, a_z the accelerometer, delta_e the elevator the autopilot applied and
q' the gyro differentiated (central differences). Both are linear in their coefficients, so they
are fitted by equation-error least squares (scipy.linalg.lstsq) with the airframe file's values as
a Gaussian prior (each coefficient +-`PRIOR_FRACTION` of itself): a level survey leg excites the
slopes little, and the prior keeps what the flight cannot tell as the file says, while the
trim (what the flight always tells) moves to the aircraft's.

The angle of attack of the lift fit is asin(w / V) (w the body-axis velocity over the ground,
V the pitot's airspeed: right in calm air and in a steady horizontal wind, noise in gusts). The
moment is fitted on the lift the accelerometer measures, the way the monitor uses it:

    q' / K = a0 + a1 C_L + a2 c q / (2 V) + a3 delta_e,
    a1 = C_ma / C_La,  a2 = C_mq,  a3 = C_mde - C_ma C_Lde / C_La,  a0 = C_m0 - C_ma C_L0 / C_La,

so an error in the lift curve's slope does not leak into what the monitor predicts. Mass, inertia
and geometry are the file's. Units SI (rad, m/s, s).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import lstsq

from fdir_service.airframe.params import AirframeParams
from fdir_service.errors import ConfigError
from fdir_service.estimation.base import StepOutput

PRIOR_FRACTION = 0.3
"""Prior std of each fitted slope as a fraction of the airframe file's value."""
TRIM_PRIOR_STD = 0.2
"""Prior std of the offsets (C_L0; C_m0' in C_m): what any steady flight tells, so left to the data."""
LIFT_MIN_R2 = 0.8
"""The lift curve is taken from the flight only when its fit explains this much of C_L (the angle of
attack of the fit is the ground velocity's, wrong in gusts); else the file's is kept."""
NEEDED_ROWS = ("w", "q", "az", "airspeed")
"""Rows `identify` needs in every frame it uses."""
MIN_FRAMES = 200
"""At least 10 s of usable frames at 20 Hz."""


@dataclass
class FlightFrames:
    """A flight's frames: t (K,) s, y (K, m) SI over `rows`, mask (K, m) bool, u (K, 2) applied input."""

    rows: tuple[str, ...]
    t: np.ndarray
    y: np.ndarray
    mask: np.ndarray
    u: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """(K,) values of row `name`, NaN where it did not arrive."""
        j = self.rows.index(name)
        return np.where(self.mask[:, j], self.y[:, j], np.nan)


@dataclass
class Coefficient:
    """One fitted coefficient: the file's value, the flight's estimate and its posterior std."""

    name: str
    prior: float
    estimate: float
    std: float


@dataclass
class Identification:
    """The fitted airframe and how well the flight supports it."""

    params: AirframeParams
    coefficients: list[Coefficient]
    frames_used: int
    lift_residual_std: float          # RMS residual of C_L
    lift_r2: float                    # NaN: C_L did not vary
    moment_residual_std: float        # RMS residual of q' (rad/s^2)
    moment_r2: float
    moment_residual_std_before: float  # RMS q' residual of the file's airframe (rad/s^2)

    def report(self) -> str:
        """A table of the coefficients and the fit quality, for the terminal."""
        lines = [f"frames used: {self.frames_used}",
                 f"lift C_L:  residual RMS {self.lift_residual_std:.4f}, R^2 {self.lift_r2:.3f}"
                 + ("" if self.lift_r2 >= LIFT_MIN_R2 else f" (< {LIFT_MIN_R2}: the file's lift curve kept)"),
                 f"pitch q':  residual RMS {self.moment_residual_std:.3f} rad/s^2 (file's airframe: "
                 f"{self.moment_residual_std_before:.3f}), R^2 {self.moment_r2:.3f}",
                 f"{'coefficient':<12}{'file':>10}{'fitted':>10}{'+- std':>10}"]
        lines += [f"{c.name:<12}{c.prior:>10.4f}{c.estimate:>10.4f}{c.std:>10.4f}" for c in self.coefficients]
        return "\n".join(lines)


# ----------------------------------------------------------------------------- frames of a log

class _FrameTap:
    """A stand-in filter that keeps every frame the service's pipeline assembles."""

    name = "TAP"

    def __init__(self, estimator) -> None:
        self.fault_ids = tuple(f.id for f in estimator.faults)
        self.frames: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
        self.n = 5 + len(self.fault_ids)

    def step(self, t, y, mask, u) -> StepOutput:
        self.frames.append((float(t), np.array(y, float), np.array(mask, bool), np.array(u, float)[:2]))
        nf = len(self.fault_ids)
        return StepOutput(t, np.zeros(self.n), None, self.fault_ids, np.zeros(nf), np.zeros(nf), 1.0, False)

    def top_particles(self, k: int = 20):
        return np.zeros((1, self.n)), np.ones(1)


def flight_frames(log_path: str | Path, estimator: str = "aerosonde-robust") -> FlightFrames:
    """The frames of a recording of `fdir run`, assembled by its recorded service config with the
    rows of `estimator` (which must list NEEDED_ROWS; the service config must map them)."""
    from fdir_service.estimator_config import estimator_document
    from fdir_service.recording.logtools import McapLog
    from fdir_service.replay import ReplayError, build_pipeline, raw_input, recorded_setup

    log = McapLog(log_path)
    setup = dict(recorded_setup(log))
    setup["estimator_doc"], _ = estimator_document(estimator)
    taps: list[_FrameTap] = []

    def factory(name, est, rng, particles, x0=None):
        taps.append(_FrameTap(est))
        return taps[-1]

    try:
        pipe = build_pipeline(setup, filter_name=None, particles=None, seed=None, observers=(),
                              filter_factory=factory)
    except ConfigError as exc:
        raise ReplayError(f"{log.path}: its service config cannot feed estimator {estimator!r} "
                          f"(identify needs rows {', '.join(NEEDED_ROWS)}): {exc}") from None
    inputs = raw_input(log)
    for t_ns, data in inputs:
        pipe.feed(data, t_ns)
    if inputs:
        pipe.close(inputs[-1][0])
    frames = [f for tap in taps for f in tap.frames]
    if not frames:
        raise ReplayError(f"{log.path}: no frame could be assembled from the recorded input")
    t, y, mask, u = (np.array(c) for c in zip(*frames, strict=True))
    return FlightFrames(pipe.config.estimator.measurements, t, y, mask, u)


# ----------------------------------------------------------------------------- the fits

def _ridge(A: np.ndarray, b: np.ndarray, prior: np.ndarray, prior_std: np.ndarray,
           noise_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of A x = b (noise std noise_std) with the prior x ~ N(prior, diag(prior_std^2)):
    (estimate (p,), posterior std (p,))."""
    Aw = np.vstack([A / noise_std, np.diag(1.0 / prior_std)])
    bw = np.concatenate([b / noise_std, prior / prior_std])
    x, *_ = lstsq(Aw, bw)
    cov = np.linalg.inv(Aw.T @ Aw)
    return x, np.sqrt(np.diag(cov))


def _prior_std(values: np.ndarray) -> np.ndarray:
    """Offsets (first entry) broad, slopes +-PRIOR_FRACTION of the file's value."""
    std = np.maximum(PRIOR_FRACTION * np.abs(values), 1e-3)
    std[0] = TRIM_PRIOR_STD
    return std


def _r2(resid: np.ndarray, b: np.ndarray) -> float:
    """1 - var(resid) / var(b); NaN when b does not vary (a steady flight tells no slope)."""
    return float(1.0 - resid.var() / b.var()) if b.var() > 1e-12 * (1.0 + b.mean() ** 2) else float("nan")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def _usable(frames: FlightFrames) -> dict[str, np.ndarray]:
    """Per-frame signals where every needed row arrived and the gyro has both neighbours."""
    missing = [r for r in NEEDED_ROWS if r not in frames.rows]
    if missing:
        raise ValueError(f"the flight's frames lack rows {missing}; identify needs {', '.join(NEEDED_ROWS)}")
    cols = {r: frames.column(r) for r in NEEDED_ROWS}
    q = cols["q"]
    dt = np.gradient(frames.t)
    qdot = np.gradient(q, frames.t)
    ok = np.isfinite(qdot) & (dt > 0)
    for r in NEEDED_ROWS:
        ok &= np.isfinite(cols[r])
    ok &= cols["airspeed"] > 5.0
    if ok.sum() < MIN_FRAMES:
        raise ValueError(f"only {int(ok.sum())} usable frames (need {MIN_FRAMES}: 10 s with "
                         f"{', '.join(NEEDED_ROWS)} all present)")
    out = {r: v[ok] for r, v in cols.items()}
    out["qdot"], out["de"] = qdot[ok], frames.u[ok, 0]
    return out


def _fit_lift(s: dict[str, np.ndarray], p: AirframeParams) -> tuple[np.ndarray, np.ndarray, float, float]:
    V = s["airspeed"]
    qbar_S = 0.5 * p.rho * V * V * p.S
    CL = -s["az"] * p.m / qbar_S
    alpha = np.arcsin(np.clip(s["w"] / V, -0.5, 0.5))
    A = np.column_stack([np.ones_like(V), alpha, s["de"]])
    prior = np.array([p.C_L0, p.C_La, p.C_Lde])
    x, std = _ridge(A, CL, prior, _prior_std(prior), noise_std=0.02)
    resid = CL - A @ x
    return x, std, _rms(resid), _r2(resid, CL)


def _moment_terms(s: dict[str, np.ndarray], p: AirframeParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (K, 4), b (K,), K(V) (K,)) of q'/K = a0 + a1 C_L + a2 c q / 2V + a3 delta_e."""
    V = s["airspeed"]
    qbar_S = 0.5 * p.rho * V * V * p.S
    K = qbar_S * p.c / p.Jy
    CL = -s["az"] * p.m / qbar_S
    A = np.column_stack([np.ones_like(V), CL, s["q"] * p.c / (2.0 * V), s["de"]])
    return A, s["qdot"] / K, K


def _combined(p: AirframeParams) -> np.ndarray:
    """[a0, a1, a2, a3] of the moment fit for airframe p (module docstring)."""
    r = p.C_ma / p.C_La
    return np.array([p.C_m0 - r * p.C_L0, r, p.C_mq, p.C_mde - r * p.C_Lde])


def identify(frames: FlightFrames, base: AirframeParams) -> Identification:
    """Fit lift and pitching moment of `base` (the airframe file) to a fault-free flight."""
    s = _usable(frames)
    lift, lift_std, lift_res, lift_r2 = _fit_lift(s, base)
    if not lift_r2 >= LIFT_MIN_R2:            # the flight does not tell the lift curve: the file's
        lift = np.array([base.C_L0, base.C_La, base.C_Lde])
    A, b, K = _moment_terms(s, base)
    prior = _combined(base)
    before = _rms((b - A @ prior) * K)
    a, a_std = _ridge(A, b, prior, _prior_std(prior), noise_std=max(before, 1e-3) / float(np.median(K)))
    resid = b - A @ a
    C_L0, C_La, C_Lde = lift
    C_ma = a[1] * C_La
    params = dataclasses.replace(base, C_L0=float(C_L0), C_La=float(C_La), C_Lde=float(C_Lde),
                                 C_ma=float(C_ma), C_mq=float(a[2]),
                                 C_m0=float(a[0] + a[1] * C_L0), C_mde=float(a[3] + a[1] * C_Lde))
    coefs = [Coefficient(n, float(getattr(base, n)), float(getattr(params, n)), float(sd))
             for n, sd in (("C_L0", lift_std[0]), ("C_La", lift_std[1]), ("C_Lde", lift_std[2]))]
    coefs += [Coefficient(n, float(pv), float(ev), float(sd)) for n, pv, ev, sd in
              zip(("a0 (C_m0')", "a1 (C_ma/C_La)", "C_mq", "a3 (C_mde')"), prior, a, a_std, strict=True)]
    return Identification(params, coefs, int(b.size), lift_res, lift_r2, _rms(resid * K),
                          _r2(resid, b), before)


def airframe_toml(ident: Identification, base_name: str, log_name: str) -> str:
    """The identified airframe as an airframe file (every parameter; the fitted ones marked)."""
    fitted = {c.name for c in ident.coefficients}
    lines = [f"# Airframe identified by `fdir identify` from {log_name}, starting from {base_name}.",
             "# Fitted: the lift curve and the pitch balance (fdir_service/identification.py);",
             "# everything else is the starting file's.", "", "[airframe]"]
    for f in dataclasses.fields(ident.params):
        v = getattr(ident.params, f.name)
        mark = "   # fitted" if f.name in fitted or f.name in ("C_m0", "C_ma", "C_mde") else ""
        lines.append(f"{f.name} = {v!r}{mark}" if math.isfinite(v) else f"# {f.name}: not finite")
    return "\n".join(lines) + "\n"
