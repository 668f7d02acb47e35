"""merge_irl.cancel: a run's stop check, polled between steps and before publishing."""

from __future__ import annotations

import threading

import pytest

from merge_irl.cancel import CancelHook, Cancelled, cancellable, check_cancelled
from merge_irl.run_folder import publish, staging_folder


def test_check_is_a_no_op_outside_a_block_and_polls_inside():
    check_cancelled(now=True)  # outside any block: nothing to ask
    asked: list[int] = []
    stop = [False]

    def stop_requested() -> bool:
        asked.append(1)
        return stop[0]

    with cancellable(stop_requested, every_s=3600.0):
        check_cancelled()  # within the interval of the block's start: not asked
        assert asked == []
        check_cancelled(now=True)
        assert len(asked) == 1
        stop[0] = True
        check_cancelled()  # within the interval again: not asked, no error
        with pytest.raises(Cancelled):
            check_cancelled(now=True)
        with pytest.raises(Cancelled):
            CancelHook().on_end(None)
    check_cancelled(now=True)  # the block ended: no-op again
    assert Cancelled.retry is False


def test_the_check_belongs_to_the_thread_that_installed_it():
    seen: list[BaseException] = []

    def other_thread() -> None:
        try:
            check_cancelled(now=True)
        except BaseException as e:  # noqa: BLE001
            seen.append(e)

    with cancellable(lambda: True):
        t = threading.Thread(target=other_thread)
        t.start()
        t.join(10)
    assert seen == []


def test_a_cancelled_run_publishes_nothing(tmp_path):
    final = tmp_path / "run"
    stage = staging_folder(final)
    (stage / "table.parquet").write_bytes(b"x")
    with cancellable(lambda: True), pytest.raises(Cancelled):
        publish(stage, final)
    assert not final.exists() and (stage / "table.parquet").exists()
    assert publish(stage, final) == final  # outside the block: published
    assert (final / "table.parquet").read_bytes() == b"x"
