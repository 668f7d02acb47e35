"""Messages about a user's callable, in one line: the one home of the text helpers the callable
drivers' modules share."""

from __future__ import annotations

__all__ = ["one_line"]


def one_line(e: BaseException) -> str:
    """``str(e)`` with its whitespace (newlines included) collapsed to single spaces."""
    return " ".join(str(e).split())
