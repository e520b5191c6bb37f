"""fdir-service: onboard fault detection, isolation and estimation for fixed-wing UAVs."""

import os as _os
import sys as _sys

if "numpy" not in _sys.modules:
    # The same bits with and without AVX-512: numpy's AVX-512 kernels (exp, sin, sums) round
    # differently from its AVX2 ones, and a particle filter's flight diverges from the first ulp, so
    # a log replayed or a campaign flown on an AVX-512 machine was another flight (docs/recording.md,
    # "Same bits on other machines"). numpy reads this once, when it is first imported; a program
    # that imported numpy before fdir_service keeps its own choice. Set the variable to "" to let
    # numpy use every kernel the machine has.
    _os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", "X86_V4 AVX512_ICL AVX512_SPR")

__version__ = "0.1.0"
