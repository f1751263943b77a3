"""CPU-burning neighbour processes, to show an answer does not depend on the machine's load.

Light on purpose (no planner import): the processes are spawned, so each imports this module
only.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing.synchronize import Event

JOIN_S = 10.0  # s a burner is given to stop before it is terminated


def _spin(started: Event, stop: Event) -> None:
    started.set()
    x = 0
    while not stop.is_set():
        for _ in range(10_000):  # pure-Python arithmetic: one core kept busy
            x = (x * 31 + 7) % 1_000_003


@contextmanager
def cpu_burners(count: int | None = None) -> Iterator[int]:
    """Run ``count`` processes (default: one per core) spinning until the block ends; yields
    how many run. Only the processes started here are stopped (then joined)."""
    context = multiprocessing.get_context("spawn")
    n = count if count is not None else (os.cpu_count() or 1)
    stop = context.Event()
    processes = []
    try:
        for _ in range(n):
            started = context.Event()
            process = context.Process(target=_spin, args=(started, stop), daemon=True)
            process.start()
            processes.append(process)
            started.wait(timeout=30.0)
        yield n
    finally:
        stop.set()
        for process in processes:
            process.join(timeout=JOIN_S)
            if process.is_alive():
                process.terminate()
                process.join(timeout=JOIN_S)
