"""`cliutil.run`, behind every `fdir` and `sim-bridge` command, runs the command on one BLAS thread
(a filter step's products are too small for a thread pool; docs/robustness.md, "Cost") and gives
the caller's thread count back afterwards."""

from __future__ import annotations

import argparse

from threadpoolctl import threadpool_info, threadpool_limits

from fdir_service import cliutil
from fdir_service.errors import ConfigError


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


def _parser(func) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="probe")
    parser.set_defaults(func=func)
    return parser


def test_a_command_runs_on_one_blas_thread_and_the_callers_count_comes_back():
    seen: list[set[int]] = []
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        assert cliutil.run(_parser(lambda args: seen.append(_blas_threads())), []) == 0
        assert _blas_threads() == {2}
    assert seen == [{1}]


def test_a_config_error_still_exits_with_status_2_and_gives_the_threads_back(capsys):
    def fail(args):
        raise ConfigError("file.toml: key x: expected a number")

    with threadpool_limits(limits=2, user_api="blas"):
        assert cliutil.run(_parser(fail), []) == 2
        assert _blas_threads() == {2}
    assert "configuration error: file.toml: key x" in capsys.readouterr().err
