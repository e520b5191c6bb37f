"""The Aerosonde longitudinal airframe: parameters, nonlinear dynamics, trim, linearisation.

State order z = [p_d, u, w, theta, q] (m, m/s, m/s, rad, rad/s); inputs [delta_e (rad), delta_t (0..1)].
"""

from fdir_service.airframe.dynamics import INPUT_NAMES, STATE_NAMES, derivatives, rk4_step
from fdir_service.airframe.linearize import LinearModel, linearize, printed_model
from fdir_service.airframe.params import AirframeParams, load_airframe
from fdir_service.airframe.trim import Trim, trim

__all__ = [
    "STATE_NAMES",
    "INPUT_NAMES",
    "AirframeParams",
    "LinearModel",
    "Trim",
    "derivatives",
    "linearize",
    "load_airframe",
    "printed_model",
    "rk4_step",
    "trim",
]
