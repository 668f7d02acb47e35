"""Worker processes that re-import the user's script: detect it and say what to do.

Process pools here use the ``spawn`` start method: every worker starts a fresh interpreter that
imports the parent's main script before it runs anything. A script that calls a parallel job at
module level, without ``if __name__ == "__main__":``, therefore starts the job again inside each
worker. :func:`importing_main_in_worker` tells a job it is being started that way, so it can refuse
at once (instead of starting pools of its own, or hanging) with :data:`GUARD_HINT`.
"""

from __future__ import annotations

import multiprocessing

#: What the user has to change, for the error messages of the jobs that refuse.
GUARD_HINT = 'put the script\'s calls under `if __name__ == "__main__":` (worker processes re-import it)'


def importing_main_in_worker() -> bool:
    """Whether this is a spawned worker process still importing the parent's main script.

    multiprocessing sets the process's ``_inheriting`` flag for exactly that phase; it is the
    flag behind its own "bootstrapping phase" error.
    """
    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))
