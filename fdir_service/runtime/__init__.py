"""The service runtime in parts, one concept per module; `pipeline.Pipeline` composes them.

- `screening`: per-message and per-value checks; what fails is counted by a typed reason and dropped.
- `frames`: frame assembly by message timestamp (`FrameAssembler` -> `AssembledFrame`).
- `health`: estimator health checks, re-initialisation decisions, the HEARTBEAT state.
- `events`: what the runtime says, as typed objects (`Rejected`, `Reinitialised`, `LinkLost`, ...).
- `items`: monitored items (a target and its typed fault entries): grouping and per-frame view.
- `publishing`: what goes out on the link (`Publisher`), STATUSTEXT rate limits and notices.
- `pipeline`: bytes in -> the parts in sequence -> bytes out (`Pipeline`).
"""
