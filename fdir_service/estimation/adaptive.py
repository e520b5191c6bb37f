"""Adaptive transition matrix of the AJMRPF (thesis ch. 6, SPEC section 6).

For each fault j and step k, two hypothesis tests on the fault's residual with the last n
(`saddlepoint_window`) hypothesis means: H0 mean 0 against H1 mean mu1|0 (weighted mean of the
predicted amplitude A_f over mode-0 particles: where a sentinel would go) gives Pfa; H0 against
mu1|1 (weighted mean of f_j over mode-1 particles) gives Pmd. Both use the fault's sigma (the
measurement's assumed noise for a sensor fault; the amplitude estimate's standard deviation for
an actuator fault). Each is the optimum of the saddlepoint ROC search
`saddlepoint.roc_optimal(mu0, s0, mu1, s1)`. Then eq. 6.1/6.76:
pi00 = phi_fa(Pfa), pi01 = 1 - pi00, pi11 = phi_md(Pmd), pi10 = 1 - pi11.

proposal=True (not the thesis; scenario `estimator.adaptive_transition = "proposal"`): the jump
uses the Pfa-driven pi01 as a *proposal* for the 0 -> 1 move, pi10 stays the model's fixed value,
and the filter multiplies each particle's weight by P_model(transition) / P_proposal(transition)
(`log_weight_correction`), so the posterior is the fixed-matrix model's and the adaptive part only
decides where particles are spent. Reason (docs/estimation.md, "ch6"): the Pmd-driven pi10 looks at
the mode-1 mean alone, not at the data, so while a growing fault is still small (Pmd ~ 0.3) it
sends ~45 % of the young mode-1 particles back to 0 every step; and the unweighted data-driven
pi01 makes fault-free sentinels chase noise.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.jump import transition_matrices


def phi_fa(x: np.ndarray) -> np.ndarray:
    """Activation for pi00 (eq. 6.76): 0.5 / (1 + exp(20 (0.1 - x))) + 0.5."""
    return 0.5 / (1.0 + np.exp(20.0 * (0.1 - np.asarray(x, dtype=float)))) + 0.5


def phi_md(x: np.ndarray) -> np.ndarray:
    """Activation for pi11 (eq. 6.76): 1 - 0.5 / (1 + exp(20 (0.1 - x)))."""
    return 1.0 - 0.5 / (1.0 + np.exp(20.0 * (0.1 - np.asarray(x, dtype=float))))


def _default_roc() -> Callable:
    from fdir_service.estimation.saddlepoint import roc_optimal
    return roc_optimal


class AdaptiveTransition:
    """Per-fault transition matrices recomputed every step from Pfa and Pmd.

    sigma (nf,): residual standard deviation per fault (SI); window: n samples kept (thesis 3);
    roc: `roc_optimal(mu0, s0, mu1, s1, n_alpha) -> (pfa, pmd, alpha)` (default: the saddlepoint
    module). Until the window fills, the samples seen so far are used.
    """

    adaptive = True

    def __init__(self, sigma: np.ndarray, window: int = 3, n_alpha: int = 50,
                 roc: Callable | None = None, pi01: np.ndarray | float = 0.01,
                 pi10: np.ndarray | float = 0.01, proposal: bool = False,
                 noisy: np.ndarray | None = None) -> None:
        self.sigma = np.asarray(sigma, dtype=float).copy()
        nf = self.sigma.size
        self.noisy = np.zeros(nf, bool) if noisy is None else np.asarray(noisy, bool).copy()
        """(nf,) noisy-sensor faults: their test is the variance test, H0 N(0, s^2) against
        H1 N(0, (k s)^2) with k = 1 + the window's k - 1 (docs/faults.md), not a mean shift."""
        self.window = int(window)
        self.n_alpha = int(n_alpha)
        self._roc = roc
        self._mu10 = np.zeros((nf, self.window))
        self._mu11 = np.zeros((nf, self.window))
        self._count = 0
        self._next = 0
        self._s = np.repeat(self.sigma[:, None], self.window, axis=1)
        self._zero = np.zeros(self.window)
        self.pi01 = np.broadcast_to(np.asarray(pi01, dtype=float), (nf,)).copy()
        self.pi10 = np.broadcast_to(np.asarray(pi10, dtype=float), (nf,)).copy()
        self.proposal = bool(proposal)
        self.model_pi01 = self.pi01.copy()
        """(nf,) the model's fixed pi01, pi10 (the estimator's): the target of the proposal mode."""
        self.model_pi10 = self.pi10.copy()
        self.pfa = np.full(nf, 0.5)
        self.pmd = np.full(nf, 0.5)

    def matrices(self) -> np.ndarray:
        """(nf, 2, 2) transition matrices in force."""
        return transition_matrices(self.pi01, self.pi10)

    def observe(self, A: np.ndarray, F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> None:
        """This step's H1 means from the cloud before the jump, then `update` (SPEC section 6).

        A (nf, N) predicted amplitudes, F (nf, N) fault entries, modes (nf, N) bool, w (N,):
        mu1|0 = weighted mean of A over mode-0 particles, mu1|1 = of f over mode-1 particles.
        """
        w1 = modes @ w                       # (nf,) weight in mode 1
        w0 = 1.0 - w1
        s0 = (A * ~modes) @ w                # weighted sum of A over mode-0 particles
        s1 = (F * modes) @ w                 # weighted sum of f over mode-1 particles
        mu10 = np.where(w0 > 1e-12, s0 / np.maximum(w0, 1e-300), A @ w)
        mu11 = np.where(w1 > 1e-12, s1 / np.maximum(w1, 1e-300), mu10)
        self.update(mu10, mu11)

    def annotate(self, out: StepOutput) -> None:
        """Adds this step's pfa, pmd (nf,) and transition matrices (nf, 2, 2) to the output."""
        out.pfa = self.pfa.copy()
        out.pmd = self.pmd.copy()
        out.transition = self.matrices()

    def update(self, mu10: np.ndarray, mu11: np.ndarray) -> None:
        """Push this step's H1 means (nf,) and recompute pfa, pmd, pi01, pi10 (nf,)."""
        if self._roc is None:
            self._roc = _default_roc()
        # ring buffer: column (count mod window) holds the newest sample; the order of the samples
        # does not matter to the test statistic (a mean over the window)
        slot = self._next % self.window
        self._next += 1
        self._mu10[:, slot] = mu10
        self._mu11[:, slot] = mu11
        self._count = min(self._count + 1, self.window)
        for j in range(self.sigma.size):
            pfa, pmd = self._test(j, self._count)
            self.pfa[j] = min(max(pfa, 0.0), 1.0) if pfa == pfa else 0.5   # NaN -> no evidence
            self.pmd[j] = min(max(pmd, 0.0), 1.0) if pmd == pmd else 0.5
        self.pi01 = 1.0 - phi_fa(self.pfa)
        # proposal: pi01 as eq. 6.76 gives it, even below the model's (with no evidence, Pfa ~ 0.5,
        # ~2e-4: a rare sentinel then carries up to ~60x the weight; a floor at the model's pi01
        # measured worse, docs/estimation.md "ch6"); pi10 the model's
        self.pi10 = self.model_pi10.copy() if self.proposal else 1.0 - phi_md(self.pmd)

    def _test(self, j: int, k: int) -> tuple[float, float]:
        """(Pfa, Pmd) of fault j over the last k samples: the mean-shift test of H1 means mu1|0
        (Pfa) and mu1|1 (Pmd), or for a noisy sensor the variance test of H1 standard deviations
        k s with k - 1 = mu1|0 (Pfa) and mu1|1 (Pmd) (saddlepoint.pfa_pmd takes unequal variances)."""
        s, zero = self._s[j, :k], self._zero[:k]
        if self.noisy[j]:
            s10 = s * (1.0 + np.maximum(self._mu10[j, :k], 0.0))
            s11 = s * (1.0 + np.maximum(self._mu11[j, :k], 0.0))
            return (float(self._roc(zero, s, zero, s10, self.n_alpha)[0]),
                    float(self._roc(zero, s, zero, s11, self.n_alpha)[1]))
        return (float(self._roc(zero, s, self._mu10[j, :k], s, self.n_alpha)[0]),
                float(self._roc(zero, s, self._mu11[j, :k], s, self.n_alpha)[1]))

    def log_weight_correction(self, before: np.ndarray, after: np.ndarray,
                              available: np.ndarray) -> np.ndarray | None:
        """(N,) log P_model / P_proposal of each particle's mode moves this step, or None (thesis mode).

        before, after (nf, N) bool modes around the jump; available (nf,) bool: faults that could
        jump this step (the others moved under neither matrix, ratio 1).
        """
        if not self.proposal:
            return None
        with np.errstate(divide="ignore", invalid="ignore"):   # equal 0 or 1 probabilities: NaN, unused
            l01 = np.log(self.model_pi01) - np.log(self.pi01)
            l00 = np.log1p(-self.model_pi01) - np.log1p(-self.pi01)
            l10 = np.log(self.model_pi10) - np.log(self.pi10)
            l11 = np.log1p(-self.model_pi10) - np.log1p(-self.pi10)
        lw = np.where(before, np.where(after, l11[:, None], l10[:, None]),
                      np.where(after, l01[:, None], l00[:, None]))
        lw[~np.asarray(available, dtype=bool)] = 0.0
        return lw.sum(axis=0)
