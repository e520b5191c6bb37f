"""The campaign metrics (SPEC section 8). They live in `fdir_service.metrics`, shared with the replay
scorer; this module re-exports them for the campaign code."""

from fdir_service.metrics import (
    HOLD_S,
    P_THRESHOLD,
    TABLE_TIMES,
    detection_metrics,
    episode_delays,
    false_alarm_fraction,
    fault_episodes,
    finite_or_none,
    held_above,
    hold_steps_of,
    median_run,
    missed_fraction,
    rmse,
    rmse_over_runs,
    table_columns,
    time_index,
)

__all__ = [
    "HOLD_S", "P_THRESHOLD", "TABLE_TIMES", "detection_metrics", "episode_delays",
    "false_alarm_fraction", "fault_episodes", "finite_or_none", "held_above", "hold_steps_of",
    "median_run", "missed_fraction", "rmse", "rmse_over_runs", "table_columns", "time_index",
]
