"""A cache folder under build/ to one process while it is made: the Windows host's Python
(tests/slaves/test_dropin_windows.py) and Debian's virtual environment (tests/pythons.py) are
prepared once and shared by every pytest run and by the suite's parallel workers (tests/run.sh
runs ``pytest -n``); the others wait on the lock and then find the cache ready."""
from __future__ import annotations

import contextlib
import fcntl
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def cache_lock(folder: Path) -> Iterator[None]:
    """``folder`` to this process alone inside the block: an exclusive flock on ``folder.lock``
    beside it (its parent made if missing), released by the kernel too when the process dies."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    with open(folder.with_name(folder.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
