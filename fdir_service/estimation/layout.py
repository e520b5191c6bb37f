"""Fault layout: which extended-state entries are faults, and where each one acts (SPEC section 5).

The extended state is x = [z (5,), f (nf,)] with z = [p_d, u, w, theta, q] and one fault entry
per monitored fault, in the estimator file's order. A sensor fault adds to one measurement
row; an actuator fault adds to one input (it enters the dynamics like that input). A fault's type
(`estimator_config.SENSOR_FAULT_TYPES`, `ACTUATOR_FAULT_TYPES`) says how its entry evolves
(`fault_types.TypedFaults`): every type but "noisy" keeps this additive form (a stuck sensor's entry is
the offset from the truth that holds its reading; a jammed or weakened actuator's the offset from
the command); a noisy sensor's entry is k - 1 and acts on its row's likelihood, not its value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fdir_service.estimator_config import ACTUATORS, THRUST_ROW, EstimatorConfig

N_AIRFRAME = 5
"""Airframe states in the extended state: [p_d, u, w, theta, q]."""


@dataclass(frozen=True)
class FaultLayout:
    """Fault channels of an extended state.

    fault_ids, kinds ("sensor" | "actuator"), targets (measurement or input name) per fault;
    measurements: the estimator's measurement rows (row order of the measurement model);
    types: each fault's type (empty: all "bias").
    """

    fault_ids: tuple[str, ...]
    kinds: tuple[str, ...]
    targets: tuple[str, ...]
    measurements: tuple[str, ...]
    types: tuple[str, ...] = ()

    @classmethod
    def from_estimator(cls, config: EstimatorConfig) -> FaultLayout:
        """The layout of an estimator's monitored faults over its observed rows (IMU rows are inputs)."""
        return cls(tuple(f.id for f in config.faults), tuple(f.kind for f in config.faults),
                   tuple(f.target for f in config.faults), tuple(config.observed),
                   tuple(f.fault_type for f in config.faults))

    def type_of(self, j: int) -> str:
        """Fault j's type ("bias" when the layout names none)."""
        return self.types[j] if self.types else "bias"

    @property
    def typed(self) -> bool:
        """True when some fault is not a bias."""
        return any(t != "bias" for t in self.types)

    @property
    def nf(self) -> int:
        """Number of fault channels."""
        return len(self.fault_ids)

    @property
    def n(self) -> int:
        """Extended-state size 5 + nf."""
        return N_AIRFRAME + self.nf

    @property
    def fault_index(self) -> np.ndarray:
        """(nf,) extended-state index of each fault entry."""
        return np.arange(N_AIRFRAME, self.n)

    @property
    def sensor_row(self) -> np.ndarray:
        """(nf,) measurement-row index of each sensor fault that adds to its row (-1 for actuator
        faults and for noisy sensors, whose entry scales the row's noise: `noisy_row`)."""
        return np.array([self.measurements.index(t) if k == "sensor" and self.type_of(j) != "noisy"
                         else -1 for j, (k, t) in enumerate(zip(self.kinds, self.targets, strict=True))],
                        dtype=int)

    @property
    def direct_row(self) -> np.ndarray:
        """(nf,) the derived row that observes each actuator fault's input directly (the throttle
        row of `thrust.ThrustCheck` for delta_t), -1 for every other fault."""
        row = self.measurements.index(THRUST_ROW) if THRUST_ROW in self.measurements else -1
        return np.array([row if k == "actuator" and t == "delta_t" else -1
                         for k, t in zip(self.kinds, self.targets, strict=True)], dtype=int)

    @property
    def noisy_row(self) -> np.ndarray:
        """(nf,) measurement-row index of each noisy-sensor fault (-1 for every other fault)."""
        return np.array([self.measurements.index(t) if self.type_of(j) == "noisy" else -1
                         for j, t in enumerate(self.targets)], dtype=int)

    @property
    def actuator_input(self) -> np.ndarray:
        """(nf,) input index (0 delta_e, 1 delta_t) of each actuator fault (-1 for sensor faults)."""
        return np.array([ACTUATORS.index(t) if k == "actuator" else -1
                         for k, t in zip(self.kinds, self.targets, strict=True)], dtype=int)

    def input_matrix(self) -> np.ndarray:
        """(2, nf) map from fault entries to the input they add to: u_eff = u + G f."""
        G = np.zeros((len(ACTUATORS), self.nf))
        for j, i in enumerate(self.actuator_input):
            if i >= 0:
                G[i, j] = 1.0
        return G
