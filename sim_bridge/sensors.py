"""The simulated sensor suite (SPEC section 3, thesis [3.4]).

Rows in `scenario.sensors.measurements` order, SI units:
- gnss_alt  y = -p_d + f + v (+ Gauss-Markov error b_k if `gnss_gauss_markov`, eq. 3.29);
- baro_alt  the static pressure of the faulty, noisy altitude -p_d + f + v is formed with the
            barometric formula and the measurement is that pressure converted back to altitude;
- u, w, theta, q  y = state + f + v.
v is zero-mean white Gaussian noise with the scenario's true sigma; f the sensor faults that
target the row. Noise comes only from the generator handed in (one standard-normal draw of size m
per frame, plus one per elapsed Gauss-Markov sample), so it depends on the seed only.
"""

from __future__ import annotations

import numpy as np

from fdir_service.atmosphere import altitude_from_pressure, pressure_from_altitude
from sim_bridge.scenario import Scenario

# Gauss-Markov GNSS error, down axis (thesis Table B.2): driving-noise sigma, 1/k, sample time.
GM_SIGMA_M = 0.40
GM_TIME_CONSTANT_S = 1100.0
GM_SAMPLE_S = 1.0

_STATE_ROW = {"gnss_alt": 0, "baro_alt": 0, "u": 1, "w": 2, "theta": 3, "q": 4}


class SensorSuite:
    """Measurements y (m,) of the true state with the scenario's noise and sensor faults."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.rng = rng
        self.names = scenario.sensors.measurements
        m = len(self.names)
        self.sigma = np.array([scenario.sensors.sigma[n] for n in self.names])
        idx = np.array([_STATE_ROW[n] for n in self.names])
        sign = np.array([-1.0 if n in ("gnss_alt", "baro_alt") else 1.0 for n in self.names])
        # y_clean = H z, H (m, 5) selects the state (altitude = -p_d).
        self.H = np.zeros((m, 5))
        self.H[np.arange(m), idx] = sign
        # Fault routing: y += S f, S (m, nf) with a 1 where sensor fault j targets row i.
        self.S = np.zeros((m, len(scenario.faults)))
        for j, ch in enumerate(scenario.faults):
            if ch.kind == "sensor":
                self.S[self.names.index(ch.target), j] = 1.0
        self.baro_row = self.names.index("baro_alt") if "baro_alt" in self.names else None
        self.gnss_row = self.names.index("gnss_alt") if "gnss_alt" in self.names else None
        self.gauss_markov = scenario.sensors.gnss_gauss_markov and self.gnss_row is not None
        self.reset()

    def reset(self) -> None:
        """Gauss-Markov error back to 0 (the generator is not rewound)."""
        self.gnss_error_m = 0.0
        self._gm_samples = 0
        self.last_static_pressure_pa = float("nan")

    def _advance_gauss_markov(self, t: float) -> None:
        """b_{n+1} = exp(-Ts / tau) b_n + eta, eta ~ N(0, 0.40^2) m, one sample per Ts = 1 s (eq. 3.29)."""
        target = int(np.floor(t / GM_SAMPLE_S + 1e-9))
        decay = np.exp(-GM_SAMPLE_S / GM_TIME_CONSTANT_S)
        while self._gm_samples < target:
            self.gnss_error_m = decay * self.gnss_error_m + GM_SIGMA_M * self.rng.standard_normal()
            self._gm_samples += 1

    def measure(self, z_true: np.ndarray, t: float, fault_values: np.ndarray) -> np.ndarray:
        """y (m,) at time t (s) for the true state z_true (5,) and fault values (nf,), SI.

        Also sets `last_static_pressure_pa` (Pa): the barometer's pressure if the scenario has
        one, else the noise-free static pressure of the true altitude.
        """
        z_true = np.asarray(z_true, dtype=float)
        noise = self.sigma * self.rng.standard_normal(self.sigma.size)
        y = self.H @ z_true + self.S @ np.asarray(fault_values, dtype=float) + noise
        if self.gauss_markov:
            self._advance_gauss_markov(t)
            y[self.gnss_row] += self.gnss_error_m
        if self.baro_row is not None:
            p = pressure_from_altitude(float(y[self.baro_row]))
            self.last_static_pressure_pa = p
            y[self.baro_row] = altitude_from_pressure(p)
        else:
            self.last_static_pressure_pa = pressure_from_altitude(-float(z_true[0]))
        return y
