"""`fdir identify`: the longitudinal airframe fitted to a fault-free flight recorded by the service.

What the robust monitor needs of its airframe is the pitch balance of `kinematic.PitchMoment`:

    q' / K(V) = C_m0 + C_ma alpha + C_mq c q / (2 V) + C_mde delta_e,   K = qbar S c / J_y,
    C_L       = -a_z m / (qbar S) = C_L0 + C_La alpha + C_Lde delta_e   (linear below stall),

with V the pitot's airspeed, a_z the accelerometer and delta_e the elevator the autopilot applied.
Both are linear in their coefficients, so they are fitted by least squares (scipy.linalg.lstsq)
with the airframe file's values as a Gaussian prior (each slope +-`PRIOR_FRACTION` of itself): a
level survey leg excites the slopes little, and the prior keeps what the flight cannot tell as the
file says, while the trim (what the flight always tells) moves to the aircraft's.

The angle of attack of the lift fit is asin(w / V) (w the body-axis velocity over the ground,
V the pitot's airspeed: right in calm air and in a steady horizontal wind, noise in gusts). The
moment is fitted on the lift the accelerometer measures, the way the monitor uses it:

    q' / K = a0 + a1 C_L + a2 c q / (2 V) + a3 delta_e,
    a1 = C_ma / C_La,  a2 = C_mq,  a3 = C_mde - C_ma C_Lde / C_La,  a0 = C_m0 - C_ma C_L0 / C_La,

so an error in the lift curve's slope does not leak into what the monitor predicts. Three things
keep this fit honest on a real flight (`_moment_rows`, `_fit_moment`):

- **One row per frame interval.** The input of frame k is the elevator held since frame k - 1
  (`fdir_service.runtime.frames`: the input of frame k is u_{k-1}), so a row is the interval (k-1, k]: q' the
  gyro's forward difference over it, the lift, pitch rate and airspeed at its midpoint (the mean
  of its ends), and that held elevator. A central difference with the elevator of one end mixes two
  elevators and, in closed loop, fitted a positive pitch damping even in calm air.
- **Instrumental variables.** The accelerometer's noise (and a gust inside a frame) is noise in the
  regressor C_L, which least squares answers with slopes shrunk towards zero (by a quarter on
  real-turbulence and real-jsbsim, more in the elevator's C_mde'). The regressors of the intervals
  two and three frames back (`INSTRUMENT_LAGS`: they share no sample with the row's) are the
  instruments: two-stage least squares, the prior applied in the second stage.
- **Physical signs.** A slope whose fit has the opposite sign of the file's (an unstable pitch
  damping C_mq > 0, say: a turbulence model the equation lacks, such as JSBSim's rotational gusts)
  is not physics the monitor can use: it is kept at the file's value, and the others refitted.

Mass, inertia and geometry are the file's. Units SI (rad, m/s, s).

It also prints what the autopilot's airspeed hold lets through (`airspeed_spread`): the pitot's
spread about its minute mean beyond its noise, the floor for a pitot-watching estimator's
`[parts] held_airspeed_sigma`, and how soon it is gone (`held_airspeed_tau`: its autocorrelation's
1/e time, for `held_airspeed_tau_s`) (docs/faults.md, "The pitot and the wind").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import lstsq
from scipy.ndimage import uniform_filter1d

from fdir_service.airframe.params import AirframeParams
from fdir_service.errors import ConfigError
from fdir_service.estimation.base import StepOutput
from fdir_service.propulsion_identification import PropulsionFit, fit_propulsion

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
    kept: bool = False
    """True: the flight's fit had the opposite sign of the file's, so the file's value is kept."""


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
    airspeed_spread: float = float("nan")  # m/s: the airspeed's RMS about its minute mean, noise removed
    airspeed_noise: float = float("nan")   # m/s: the pitot's noise, from successive readings
    airspeed_tau: float = float("nan")     # s: the 1/e time of the held airspeed's deviation
    propulsion: PropulsionFit | None = None  # the throttle's thrust and the engine's lag (None: not fitted)
    propulsion_tried: bool = False    # the recording had a_x, so the propulsion was tried

    def report(self) -> str:
        """A table of the coefficients and the fit quality, for the terminal."""
        lines = [f"frames used: {self.frames_used}",
                 f"lift C_L:  residual RMS {self.lift_residual_std:.4f}, R^2 {self.lift_r2:.3f}"
                 + ("" if self.lift_r2 >= LIFT_MIN_R2 else f" (< {LIFT_MIN_R2}: the file's lift curve kept)"),
                 f"pitch q':  residual RMS {self.moment_residual_std:.3f} rad/s^2 (file's airframe: "
                 f"{self.moment_residual_std_before:.3f}), R^2 {self.moment_r2:.3f}"]
        if math.isfinite(self.airspeed_spread):
            lines.append(f"airspeed:  {self.airspeed_spread:.2f} m/s RMS about its {HOLD_MEAN_S:.0f} s mean "
                         f"beyond the pitot's noise ({self.airspeed_noise:.2f} m/s): what the airspeed "
                         f"hold lets through, a floor for [parts] held_airspeed_sigma")
        if math.isfinite(self.airspeed_tau):
            lines.append(f"           it loses its memory in {self.airspeed_tau:.2f} s: for [parts] "
                         f"held_airspeed_tau_s, a second or more")
        if self.propulsion is not None:
            lines.append(self.propulsion.report())
        elif self.propulsion_tried:
            lines.append("throttle:  not fitted, the file's propulsion kept: too few level frames, or a "
                         "throttle that hardly moved (calm air; fly in turbulence or with steps)")
        lines.append(f"{'coefficient':<12}{'file':>10}{'fitted':>10}{'+- std':>10}")
        kept = "   kept: the flight's fit had the wrong sign"
        lines += [f"{c.name:<12}{c.prior:>10.4f}{c.estimate:>10.4f}{c.std:>10.4f}" + (kept if c.kept else "")
                  for c in self.coefficients]
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
    """Per-frame signals (K,): the needed rows (NaN where missing), t, the elevator of the frame's
    input (rad), and `ok` where every needed row arrived with a usable airspeed."""
    missing = [r for r in NEEDED_ROWS if r not in frames.rows]
    if missing:
        raise ValueError(f"the flight's frames lack rows {missing}; identify needs {', '.join(NEEDED_ROWS)}")
    s = {r: frames.column(r) for r in NEEDED_ROWS}
    ok = s["airspeed"] > 5.0                      # False for NaN too
    for r in NEEDED_ROWS:
        ok &= np.isfinite(s[r])
    s["t"], s["de"], s["ok"] = np.asarray(frames.t, float), np.asarray(frames.u, float)[:, 0], ok
    return s


INSTRUMENT_LAGS = (2, 3)
"""The instruments of the row of interval (k-1, k]: the regressors of the intervals ending at
frames k-2 and k-3, which share no sample (and no sample's noise) with the row."""


def _intervals(s: dict[str, np.ndarray]) -> np.ndarray:
    """Frames k (n,) whose interval (k-1, k] and the instruments' intervals (back to frame
    k - 1 - max lag) have every needed row at both ends, time increasing."""
    ok, t = s["ok"], s["t"]
    back = max(INSTRUMENT_LAGS) + 1
    k = np.arange(back, ok.size)
    good = np.ones(k.size, dtype=bool)
    for lag in range(back + 1):
        good &= ok[k - lag]
    for lag in range(back):
        good &= t[k - lag] > t[k - lag - 1]
    k = k[good]
    if k.size < MIN_FRAMES:
        raise ValueError(f"only {k.size} usable frames (need {MIN_FRAMES}: 10 s with "
                         f"{', '.join(NEEDED_ROWS)} all present)")
    return k


def _instruments(s: dict[str, np.ndarray], k: np.ndarray, p: AirframeParams) -> np.ndarray:
    """Z (n, 1 + 3 x lags): a constant and the regressors of the intervals INSTRUMENT_LAGS back."""
    cols = [np.ones(k.size)] + [_moment_rows(s, k - lag, p)[0][:, 1:] for lag in INSTRUMENT_LAGS]
    return np.column_stack(cols)


def _lift_coefficient(az: np.ndarray, V: np.ndarray, p: AirframeParams) -> np.ndarray:
    """C_L = -a_z m / (qbar S) from the accelerometer (m/s^2) at airspeed V (m/s)."""
    return -az * p.m / (0.5 * p.rho * V * V * p.S)


def _fit_lift(s: dict[str, np.ndarray], p: AirframeParams) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The lift curve on the frames themselves: C_L at frame k is made by the elevator held since
    frame k - 1, the frame's input."""
    ok = s["ok"]
    V, w, de = s["airspeed"][ok], s["w"][ok], s["de"][ok]
    CL = _lift_coefficient(s["az"][ok], V, p)
    alpha = np.arcsin(np.clip(w / V, -0.5, 0.5))
    A = np.column_stack([np.ones_like(V), alpha, de])
    prior = np.array([p.C_L0, p.C_La, p.C_Lde])
    x, std = _ridge(A, CL, prior, _prior_std(prior), noise_std=0.02)
    resid = CL - A @ x
    return x, std, _rms(resid), _r2(resid, CL)


def _moment_rows(s: dict[str, np.ndarray], k: np.ndarray, p: AirframeParams
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (n, 4), b (n,), K(V) (n,)) of q'/K = a0 + a1 C_L + a2 c q / 2V + a3 delta_e over the frame
    intervals (k-1, k]: q' the gyro's forward difference, C_L, q and V at the midpoint, the elevator
    held over the interval (the input of frame k)."""
    j = k - 1
    Vj, Vk = s["airspeed"][j], s["airspeed"][k]
    V = 0.5 * (Vj + Vk)
    CL = 0.5 * (_lift_coefficient(s["az"][j], Vj, p) + _lift_coefficient(s["az"][k], Vk, p))
    q = 0.5 * (s["q"][j] + s["q"][k])
    qdot = (s["q"][k] - s["q"][j]) / (s["t"][k] - s["t"][j])
    K = 0.5 * p.rho * V * V * p.S * p.c / p.Jy
    A = np.column_stack([np.ones_like(V), CL, q * p.c / (2.0 * V), s["de"][k]])
    return A, qdot / K, K


def _combined(p: AirframeParams) -> np.ndarray:
    """[a0, a1, a2, a3] of the moment fit for airframe p (module docstring)."""
    r = p.C_ma / p.C_La
    return np.array([p.C_m0 - r * p.C_L0, r, p.C_mq, p.C_mde - r * p.C_Lde])


PINNED_STD = 1e-9
"""Prior std (relative to the file's value) of a slope kept at the file's: a fixed coefficient."""


def _fit_moment(A: np.ndarray, Z: np.ndarray, b: np.ndarray, prior: np.ndarray, noise_std: float
                ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Two-stage least squares of A a = b with instruments Z (n, >= 4) and the prior N(prior, std^2)
    in the second stage; slopes (a1..a3) fitted with the opposite sign of the file's are kept at the
    file's. Returns (a (4,), posterior std (4,), indices of the slopes kept)."""
    coef, *_ = lstsq(Z, A)
    A_hat = Z @ coef                               # the regressors as the instruments explain them
    std = _prior_std(prior)
    kept: list[int] = []
    while True:
        a, a_std = _ridge(A_hat, b, prior, std, noise_std)
        wrong = [i for i in (1, 2, 3) if i not in kept and a[i] * prior[i] < 0]
        if not wrong:
            return a, a_std, kept
        kept += wrong
        std[wrong] = PINNED_STD * np.maximum(np.abs(prior[wrong]), 1.0)


HOLD_MEAN_S = 60.0
"""The airspeed's spread is taken about its mean over this window (s): the catalogue's
wind_mean_tau_s, how slowly the held airspeed the monitor's gusts return to follows."""


def _about_hold_mean(t: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, float, float] | None:
    """(d, noise_var, dt): the pitot readings V (K,) at times t (K,) s (NaN where missing) less
    their HOLD_MEAN_S running mean, the window's edges cut (m/s); the pitot's noise variance from
    successive readings (var(dV) / 2, the air moving little in one frame, (m/s)^2); the median frame
    step (s). None: under 2 windows of data."""
    ok = np.isfinite(V)
    V, t = V[ok], t[ok]
    if V.size < 3 or t[-1] - t[0] < 2 * HOLD_MEAN_S:
        return None
    dt = float(np.median(np.diff(t)))
    width = max(int(round(HOLD_MEAN_S / dt)), 1)
    noise_var = 0.5 * float(np.var(np.diff(V)))
    return (V - uniform_filter1d(V, width, mode="nearest"))[width:-width], noise_var, dt


def airspeed_spread(t: np.ndarray, V: np.ndarray) -> tuple[float, float]:
    """(spread, noise) m/s of the pitot readings V (K,) at times t (K,) s, NaN where missing: the
    pitot's noise and the airspeed's RMS about its HOLD_MEAN_S mean with that noise removed (the
    estimator's held_airspeed_sigma under an airspeed hold, pitot.gust_sigma). NaN, NaN: under 2
    windows of data."""
    about = _about_hold_mean(t, V)
    if about is None:
        return float("nan"), float("nan")
    d, noise_var, _ = about
    return math.sqrt(max(float(np.var(d)) - noise_var, 0.0)), math.sqrt(noise_var)


def held_airspeed_tau(t: np.ndarray, V: np.ndarray, lags_s: float = 10.0) -> float:
    """The time (s) over which the airspeed's deviation from its HOLD_MEAN_S mean loses its memory:
    the first lag where its autocorrelation, the pitot's white noise taken out (lag 0 left out),
    falls to 1/e, interpolated between frames (the estimator's held_airspeed_tau_s under an
    airspeed hold). V (K,) m/s at times t (K,) s, NaN where missing; NaN: under 2 windows of data
    or a spread under a tenth of the noise; lags_s (s): the longest lag looked at (returned if not
    reached)."""
    about = _about_hold_mean(t, V)
    if about is None:
        return float("nan")
    d, noise_var, dt = about
    d = d - d.mean()
    held_var = float(np.var(d)) - noise_var
    if held_var <= 0.01 * noise_var:                 # a spread under a tenth of the noise: nothing to time
        return float("nan")
    lags = np.arange(1, max(int(round(lags_s / dt)), 1) + 1)
    rho = np.array([float(np.mean(d[:-k] * d[k:])) for k in lags]) / held_var
    below = np.flatnonzero(rho <= math.exp(-1.0))
    if below.size == 0:
        return float(lags[-1] * dt)
    k = int(below[0])
    if k == 0:
        return float(dt)
    r0, r1 = rho[k - 1], rho[k]
    return float((lags[k - 1] + (r0 - math.exp(-1.0)) / (r0 - r1)) * dt)


def identify(frames: FlightFrames, base: AirframeParams) -> Identification:
    """Fit lift and pitching moment of `base` (the airframe file) to a fault-free flight."""
    s = _usable(frames)
    k = _intervals(s)
    lift, lift_std, lift_res, lift_r2 = _fit_lift(s, base)
    if not lift_r2 >= LIFT_MIN_R2:            # the flight does not tell the lift curve: the file's
        lift = np.array([base.C_L0, base.C_La, base.C_Lde])
    A, b, K = _moment_rows(s, k, base)
    Z = _instruments(s, k, base)
    prior = _combined(base)
    before = _rms((b - A @ prior) * K)
    a, a_std, kept = _fit_moment(A, Z, b, prior, noise_std=max(before, 1e-3) / float(np.median(K)))
    resid = b - A @ a
    C_L0, C_La, C_Lde = lift
    C_ma = a[1] * C_La
    params = dataclasses.replace(base, C_L0=float(C_L0), C_La=float(C_La), C_Lde=float(C_Lde),
                                 C_ma=float(C_ma), C_mq=float(a[2]),
                                 C_m0=float(a[0] + a[1] * C_L0), C_mde=float(a[3] + a[1] * C_Lde))
    coefs = [Coefficient(n, float(getattr(base, n)), float(getattr(params, n)), float(sd))
             for n, sd in (("C_L0", lift_std[0]), ("C_La", lift_std[1]), ("C_Lde", lift_std[2]))]
    names = ("a0 (C_m0')", "a1 (C_ma/C_La)", "C_mq", "a3 (C_mde')")
    coefs += [Coefficient(names[i], float(prior[i]), float(a[i]), float(a_std[i]), i in kept)
              for i in range(4)]
    spread, noise = airspeed_spread(s["t"], s["airspeed"])
    propulsion = _propulsion(frames, s, params)
    if propulsion is not None:
        params = propulsion.apply(params)
    return Identification(params, coefs, int(b.size), lift_res, lift_r2, _rms(resid * K),
                          _r2(resid, b), before, spread, noise, held_airspeed_tau(s["t"], s["airspeed"]),
                          propulsion, "ax" in frames.rows)


def _propulsion(frames: FlightFrames, s: dict[str, np.ndarray],
                params: AirframeParams) -> PropulsionFit | None:
    """The flight's propulsion (`propulsion_identification.fit_propulsion`) on the fitted `params`;
    None without an ax row (or too few level frames)."""
    if "ax" not in frames.rows:
        return None
    nan = np.full(s["t"].size, np.nan)
    cols = {r: frames.column(r) if r in frames.rows else nan for r in ("ax", "theta", "u", "w")}
    cols.update(az=s["az"], airspeed=s["airspeed"], de=s["de"], q=s["q"],
                dt=np.asarray(frames.u, float)[:, 1])
    return fit_propulsion(cols, params, float(np.median(np.diff(s["t"]))))


def airframe_toml(ident: Identification, base_name: str, log_name: str) -> str:
    """The identified airframe as an airframe file (every parameter; the fitted ones marked)."""
    fitted = {c.name for c in ident.coefficients}
    fitted |= {"k_motor", "C_prop"} if ident.propulsion is not None else set()
    what = "the lift curve, the pitch balance and the propulsion" if ident.propulsion else \
        "the lift curve and the pitch balance"
    lines = [f"# Airframe identified by `fdir identify` from {log_name}, starting from {base_name}.",
             f"# Fitted: {what} (fdir_service/identification.py);",
             "# everything else is the starting file's.", "", "[airframe]"]
    for f in dataclasses.fields(ident.params):
        v = getattr(ident.params, f.name)
        mark = "   # fitted" if f.name in fitted or f.name in ("C_m0", "C_ma", "C_mde") else ""
        lines.append(f"{f.name} = {v!r}{mark}" if math.isfinite(v) else f"# {f.name}: not finite")
    return "\n".join(lines) + "\n"
