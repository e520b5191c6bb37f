"""The simulated sensor suite (SPEC section 3, thesis [3.4]).

Rows in `scenario.sensors.measurements` order, SI units:
- gnss_alt  y = -p_d + f + v (+ Gauss-Markov error b_k if `gnss_gauss_markov`, eq. 3.29);
- baro_alt  the static pressure of the faulty, noisy altitude -p_d + f + v is formed with the
            barometric formula and the measurement is that pressure converted back to altitude;
- u, w, theta, q  y = state + f + v.
- airspeed  the pitot: |air-relative velocity| + f + v (the truth's `air_data`);
- ax, az    the accelerometer: body-axis specific force (forward, down; m/s^2) + f + v.
v is zero-mean white Gaussian noise with the scenario's true sigma; f the bias sensor faults that
target the row. Typed sensor faults (stuck, noisy, blocked: `sim_bridge.fault_types`) scale the
row's noise draw or replace its reading. Realism (off in the thesis scenarios, docs/real-world.md):
a GNSS fix only every 1/gnss_rate_hz s (the row is missing in between), reporting the altitude of
gnss_latency_s before (whole frames); a barometer bias random walk; a q-gyro bias (constant per run
plus a random walk).
Noise comes only from the generator handed in (one standard-normal draw of size m per frame, plus
one per elapsed Gauss-Markov sample and one per active bias walk), so it depends on the seed only.
"""

from __future__ import annotations

import numpy as np

from fdir_service.atmosphere import altitude_from_pressure, pressure_from_altitude
from sim_bridge.fault_types import SensorFaults
from sim_bridge.scenario import Scenario

# Gauss-Markov GNSS error, down axis (thesis Table B.2): driving-noise sigma, 1/k, sample time.
GM_SIGMA_M = 0.40
GM_TIME_CONSTANT_S = 1100.0
GM_SAMPLE_S = 1.0

_STATE_ROW = {"gnss_alt": 0, "baro_alt": 0, "u": 1, "w": 2, "theta": 3, "q": 4}
AIR_ROWS = ("airspeed", "ax", "az", "roll", "v", "p", "r")
"""Rows measured from the truth's air data (`world.AirData`), not from z."""


def _air_value(air, i: int) -> float:
    """The clean reading of air row AIR_ROWS[i] from the truth's `AirData`."""
    if i == 0:
        return air.airspeed_mps
    return air.specific_force[i - 1] if i < 3 else air.lateral[i - 3]


class SensorSuite:
    """Measurements y (m,) of the true state with the scenario's noise and sensor faults."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.rng = rng
        self.names = scenario.sensors.measurements
        m = len(self.names)
        self.sigma = np.array([scenario.sensors.sigma[n] for n in self.names])
        # y_clean = H z, H (m, 5) selects the state (altitude = -p_d); air-data rows have no H row
        self.H = np.zeros((m, 5))
        for r, n in enumerate(self.names):
            if n in _STATE_ROW:
                self.H[r, _STATE_ROW[n]] = -1.0 if n in ("gnss_alt", "baro_alt") else 1.0
        self.air_rows = [(r, AIR_ROWS.index(n)) for r, n in enumerate(self.names) if n in AIR_ROWS]
        # Fault routing: y += S f, S (m, nf) with a 1 where bias sensor fault j targets row i.
        self.S = np.zeros((m, len(scenario.faults)))
        for j, ch in enumerate(scenario.faults):
            if ch.kind == "sensor" and ch.fault_type in ("bias", "drift"):   # drift: a ramp, added
                self.S[self.names.index(ch.target), j] = 1.0
        self.typed = SensorFaults(scenario.faults, self.names)
        self.baro_row = self.names.index("baro_alt") if "baro_alt" in self.names else None
        self.gnss_row = self.names.index("gnss_alt") if "gnss_alt" in self.names else None
        self.q_row = self.names.index("q") if "q" in self.names else None
        self.gauss_markov = scenario.sensors.gnss_gauss_markov and self.gnss_row is not None
        self.config = scenario.sensors
        self.dt = scenario.dt_s
        self.reset()

    def reset(self) -> None:
        """Gauss-Markov error and biases back to their start (the generator is not rewound)."""
        self.gnss_error_m = 0.0
        self._gm_samples = 0
        self.last_static_pressure_pa = float("nan")
        self.last_mask = np.ones(len(self.names), dtype=bool)
        self.last_fault_truth = np.full(len(self.scenario.faults), np.nan)
        self.typed.reset()
        self.baro_bias_m = 0.0
        cfg = self.config
        self.gyro_bias = cfg.gyro_bias_sigma * self.rng.standard_normal() if cfg.gyro_bias_sigma else 0.0
        self._altitudes: list[float] = []          # true altitudes of the last frames (latency)
        self._last_fix = -1

    def _advance_gauss_markov(self, t: float) -> None:
        """b_{n+1} = exp(-Ts / tau) b_n + eta, eta ~ N(0, 0.40^2) m, one sample per Ts = 1 s (eq. 3.29)."""
        target = int(np.floor(t / GM_SAMPLE_S + 1e-9))
        decay = np.exp(-GM_SAMPLE_S / GM_TIME_CONSTANT_S)
        while self._gm_samples < target:
            self.gnss_error_m = decay * self.gnss_error_m + GM_SIGMA_M * self.rng.standard_normal()
            self._gm_samples += 1

    def measure(self, z_true: np.ndarray, t: float, fault_values: np.ndarray, air=None,
                active: np.ndarray | None = None) -> np.ndarray:
        """y (m,) at time t (s) for the true state z_true (5,) and fault profile values (nf,), SI;
        air: the truth's `AirData` (needed only for airspeed / ax / az rows); active (nf,) bool:
        each fault's activity (`fault_types.activity`; None: value != 0, enough for bias faults).

        Also sets `last_static_pressure_pa` (Pa): the barometer's pressure if the scenario has
        one, else the noise-free static pressure of the true altitude; `last_mask` (m,): the
        rows measured this frame (False: no GNSS fix this frame); and `last_fault_truth` (nf,):
        the typed sensor faults' additive-equivalent truth (NaN for the other channels).
        """
        z_true = np.asarray(z_true, dtype=float)
        fault_values = np.asarray(fault_values, dtype=float)
        noise = self.sigma * self.rng.standard_normal(self.sigma.size)
        if self.typed.typed:
            active = fault_values != 0.0 if active is None else active
            self.typed.scale_noise(noise, fault_values, active)
        y = self.H @ z_true + self.S @ fault_values + noise
        for r, i in self.air_rows:
            y[r] += _air_value(air, i)
        if self.gauss_markov:
            self._advance_gauss_markov(t)
            y[self.gnss_row] += self.gnss_error_m
        self._realism(y, z_true, t)
        if self.typed.typed:
            self.last_fault_truth = self.typed.apply(y, self.clean(z_true, air), noise, fault_values,
                                                     active, -float(z_true[0]))
        if self.baro_row is not None:
            p = pressure_from_altitude(float(y[self.baro_row]))
            self.last_static_pressure_pa = p
            y[self.baro_row] = altitude_from_pressure(p)
        else:
            self.last_static_pressure_pa = pressure_from_altitude(-float(z_true[0]))
        return y

    def clean(self, z_true: np.ndarray, air=None) -> np.ndarray:
        """(m,) the noise-free, fault-free reading of every row: H z_true, air data on air rows."""
        y = self.H @ np.asarray(z_true, dtype=float)
        for r, i in self.air_rows:
            y[r] += _air_value(air, i)
        return y

    def _realism(self, y: np.ndarray, z_true: np.ndarray, t: float) -> None:
        """GNSS rate and latency, baro and gyro biases, in place on y (off: nothing, no draws)."""
        cfg = self.config
        if self.gnss_row is not None and (cfg.gnss_rate_hz or cfg.gnss_latency_s):
            self._gnss_fix(y, z_true, t)
        if cfg.baro_bias_walk and self.baro_row is not None:
            self.baro_bias_m += cfg.baro_bias_walk * np.sqrt(self.dt) * self.rng.standard_normal()
            y[self.baro_row] += self.baro_bias_m
        if cfg.gyro_bias_walk:
            self.gyro_bias += cfg.gyro_bias_walk * np.sqrt(self.dt) * self.rng.standard_normal()
        if self.q_row is not None and self.gyro_bias:
            y[self.q_row] += self.gyro_bias

    def _gnss_fix(self, y: np.ndarray, z_true: np.ndarray, t: float) -> None:
        """The GNSS row: the altitude of `gnss_latency_s` before (whole frames); missing between fixes."""
        cfg = self.config
        self._altitudes.append(-float(z_true[0]))
        lag = int(round(cfg.gnss_latency_s / self.dt))
        self._altitudes = self._altitudes[-(lag + 1):]
        y[self.gnss_row] += self._altitudes[0] - (-float(z_true[0]))
        fix = int(np.floor(t * cfg.gnss_rate_hz + 1e-9)) if cfg.gnss_rate_hz else self._last_fix + 1
        self.last_mask[self.gnss_row] = fix != self._last_fix
        self._last_fix = fix
