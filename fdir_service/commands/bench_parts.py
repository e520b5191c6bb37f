"""`fdir bench --parts`: where a particle filter's step goes, slot by slot (docs/robustness.md, "Cost").

Each slot of the filter's recipe (predict, jump, sentinel weighting, correction) and its resampling
(the resampler and the regulariser, on the steps that resample) is timed on its own over the same
model frames as `fdir bench`, after a warm-up; the rest of the step (weights, estimate, output) is
what the step took beyond them. Timing wraps the parts' methods on the filter's own objects for the
run and puts them back after.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fdir_service.commands.bench import _clock

SLOTS = (("predict", "predict", "predict"), ("jump", "jump", "jump"),
         ("sentinels", "sentinel_weighting", "weigh"), ("correction", "correction", "update"))
"""(column, the filter's `parts` attribute, its method) per timed slot."""

_ABSENT = object()


class _Timer:
    """Accumulates the clock time of the wrapped calls while `on`."""

    def __init__(self, tick: Callable[[], float]) -> None:
        self.tick, self.on = tick, False
        self.total: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self.saved: list[tuple[Any, str, Any]] = []

    def restore(self) -> None:
        """Every wrapped method as it was (the class's, or the instance's own)."""
        for owner, method, before in reversed(self.saved):
            if before is _ABSENT:
                delattr(owner, method)
            else:
                setattr(owner, method, before)

    def wrap(self, owner: Any, method: str, label: str) -> None:
        inner = getattr(owner, method)
        self.total[label], self.calls[label] = 0.0, 0
        self.saved.append((owner, method, vars(owner).get(method, _ABSENT)))

        def timed(*args, **kwargs):
            if not self.on:
                return inner(*args, **kwargs)
            t0 = self.tick()
            out = inner(*args, **kwargs)
            self.total[label] += self.tick() - t0
            self.calls[label] += 1
            return out

        setattr(owner, method, timed)


def time_parts(f: Any, frames: Any, steps: int, warmup: int = 50, clock: str = "cpu") -> dict[str, Any]:
    """{"step": mean us per step, SLOT: mean us per step, "resample": mean us per step,
    "resample_call": us per resampling step, "resample_share": share of steps that resampled} for
    a `ParticleFilter` f over frames (t, y, mask, u arrays of at least warmup + steps frames)."""
    timer = _Timer(_clock(clock))
    owners = [(getattr(f.parts, attr), method, label) for label, attr, method in SLOTS]
    owners.append((f, "_resample", "resample"))
    step_total = 0.0
    try:
        for owner, method, label in owners:
            timer.wrap(owner, method, label)
        for k in range(warmup + steps):
            timer.on = k >= warmup
            t0 = timer.tick()
            f.step(frames.t[k], frames.y[k], frames.mask[k], frames.u[k])
            step_total += (timer.tick() - t0) if timer.on else 0.0
    finally:
        timer.restore()
    out = {"step": step_total / steps * 1e6}
    out.update({label: timer.total[label] / steps * 1e6 for _, _, label in owners})
    calls = timer.calls["resample"]
    out["resample_call"] = timer.total["resample"] / calls * 1e6 if calls else 0.0
    out["resample_share"] = calls / steps
    return out


def print_parts(rows: dict[str, dict[str, Any]], title: str) -> None:
    """The table of `time_parts` per filter."""
    print(title)
    labels = [label for label, _, _ in SLOTS]
    print(f"{'filter':10s} {'step':>8s} " + " ".join(f"{c:>10s}" for c in labels)
          + f" {'resample':>10s}  {'the rest':>8s}   resampling steps")
    for name, r in rows.items():
        rest = r["step"] - sum(r[c] for c in labels) - r["resample"]
        print(f"{name:10s} {r['step']:8.1f} " + " ".join(f"{r[c]:10.1f}" for c in labels)
              + f" {r['resample']:10.1f}  {rest:8.1f}   {r['resample_share']:.0%} at "
              f"{r['resample_call']:.0f} us each")
