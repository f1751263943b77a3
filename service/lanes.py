"""Admission control: bounded lanes of work, each with its own slots and its own queue.

A :class:`Gate` admits at most ``slots + queue`` pieces of work at once: ``slots`` run, the
others wait in arrival order, and one more is refused at once with a 503 that carries
``Retry-After`` and names the limit. A piece of work may say by when it must have started
(``start_by``, a :func:`time.monotonic` time: a request's budget counts from its arrival);
one still waiting then is refused with a 503 too, without having cost anything.

A :class:`Lane` is a gate whose slots are worker processes (:func:`service.workers.
serve_tasks`), one task at a time each. A task that must stop (its deadline passed, its
client went away, its job was cancelled) stops for real: its process is killed, which frees
the slot at once, and a fresh process takes its place on the next task. A process that dies
fails only the task it ran. The service has three lanes per service worker (``Lanes``):
interactive work (plans, Twister steps, jumps), background jobs (roadmap builds, asynchronous
plans) and uploads (mesh parsing, surfaces and BVH builds, one at a time).
"""

from __future__ import annotations

import asyncio
import inspect
import logging
import math
import multiprocessing
import os
import time
from collections import deque
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any, TypeVar, cast

from service.errors import ApiError
from service.metrics import Metrics
from service.settings import RETRY_AFTER_S, SHORT_DEMAND_S, UPLOAD_CONCURRENCY, Settings
from service.workers import compute_niceness, lower_priority, serve_tasks

T = TypeVar("T")
log = logging.getLogger("gecko.lanes")
JOIN_KILLED_S = 5.0  # s to wait for a killed process to be reaped


class Ticket:
    """An admitted piece of work's place in its gate, held until :meth:`release`."""

    def __init__(self, gate: Gate, short: bool = False) -> None:
        self._gate: Gate | None = gate
        self.short = short  # short work (a Twister step): its own queue, served first

    def release(self) -> None:
        """Leave the gate (idempotent)."""
        if self._gate is not None:
            self._gate._leave(self.short)
            self._gate = None


@dataclass(frozen=True, slots=True)
class ShortLine:
    """Short work's own line in a gate (Twister steps): at most ``queue`` of it waiting (a
    refusal names ``setting``, the bound's environment variable), served before the long work
    waiting; ``reserved`` slots that long work leaves to it while it keeps coming."""

    queue: int = 0
    setting: str = ""
    reserved: int = 0


class Gate:
    """At most ``slots`` pieces of work at once, ``queue`` more waiting, the rest refused.

    Short work (Twister steps: tens of ms) has its own line (``short``: a bound on its
    waiting, served before the long work waiting); and while short work keeps coming (some
    admitted within the last ``SHORT_DEMAND_S``), long work holds at most ``slots -
    short.reserved`` slots, so a step never waits behind plans and jumps that take seconds.
    Past that window long work may use every slot again. A line holds only work still
    waiting (work handed a slot or gone is taken out of it). (A third process for steps
    alone instead shared the two cores three ways: steps alone at 4 to 64 clients ran 35-41
    per second, p99 184-349 ms, against 44-49 per second, p99 150-220 ms, on two processes,
    4 steps waiting in both.)
    """

    def __init__(
        self,
        name: str,
        *,
        slots: int,
        queue: int,
        setting: str,
        metrics: Metrics,
        short: ShortLine = ShortLine(),
    ) -> None:
        if not 0 <= short.reserved < max(slots, 1):
            message = f"reserved: 0 to {slots - 1} slots of {slots}, got {short.reserved}"
            raise ValueError(message)
        self.name = name
        self.slots = slots
        self.queue = queue
        self.setting = setting  # the environment variable of the queue's bound (for messages)
        self.short = short
        self._metrics = metrics
        self._admitted = {False: 0, True: 0}  # admitted (running or waiting), long / short
        self._running = {False: 0, True: 0}
        self._free = slots
        self._waiters: dict[bool, deque[asyncio.Future[None]]] = {False: deque(), True: deque()}
        self._short_seen = -math.inf  # monotonic s: when short work was last admitted
        self._recheck: asyncio.TimerHandle | None = None  # long work held back until then

    @property
    def running(self) -> int:
        """Pieces of work holding a slot now."""
        return self.slots - self._free

    @property
    def waiting(self) -> int:
        """Admitted pieces of work not holding a slot yet (the queue's depth)."""
        return sum(self._admitted.values()) - self.running

    @property
    def live_processes(self) -> int:
        """Processes of the gate alive now (none: a plain gate runs work in the caller)."""
        return 0

    def process_ids(self) -> list[int]:
        """Ids of the gate's live processes."""
        return []

    def _refuse(self, code: str, message: str) -> ApiError:
        self._metrics.refused.labels(self.name, code).inc()
        retry = RETRY_AFTER_S[self.name]
        return ApiError(
            503, code, f"{message}; retry in {retry} s", None, {"Retry-After": str(retry)}
        )

    def admit(self, short: bool = False) -> Ticket:
        """A place in the gate, or a 503 (``queue_full``) when every place is taken: long
        work past ``slots + queue`` of it admitted, short work past ``short.queue`` of it
        waiting beyond the free slots."""
        admitted, running = self._admitted[short], self._running[short]
        # short work admitted and not running yet (some about to take a free slot)
        if short and admitted - running >= self.short.queue + self._free:
            message = (
                f"the {self.name} queue of Twister steps is full ({running} running, "
                f"{admitted - running - self._free} waiting; limit "
                f"{self.short.setting}={self.short.queue})"
            )
            raise self._refuse("queue_full", message)
        if not short and admitted >= self.slots + self.queue:
            message = (
                f"the {self.name} queue is full ({running} running, {admitted - running} "
                f"waiting; limit {self.setting}={self.queue})"
            )
            raise self._refuse("queue_full", message)
        self._admitted[short] += 1
        if short:
            self._short_seen = time.monotonic()
        return Ticket(self, short)

    def _leave(self, short: bool = False) -> None:
        self._admitted[short] -= 1

    def _long_slots(self) -> int:
        """Slots long work may hold now: all but ``short.reserved`` while short work is
        coming."""
        if time.monotonic() - self._short_seen < SHORT_DEMAND_S:
            return self.slots - self.short.reserved
        return self.slots

    def _can_start(self, short: bool) -> bool:
        return self._free > 0 and (short or self._running[False] < self._long_slots())

    def _hand(self, short: bool) -> None:
        self._free -= 1
        self._running[short] += 1

    async def take_slot(self, start_by: float | None = None, short: bool = False) -> None:
        """Wait in line for a slot (short work in its own line, served first); a 503
        (``queue_timeout``) if ``start_by`` (monotonic s) passes first. The caller gives the
        slot back with :meth:`give_slot`."""
        ahead = self._waiters[True] or (not short and self._waiters[False])
        if self._can_start(short) and not ahead:
            self._hand(short)
            return
        waiter = asyncio.get_running_loop().create_future()
        self._waiters[short].append(waiter)
        self._dispatch()  # long work held back only by the reservation: starts when it lapses
        timeout = None if start_by is None else start_by - time.monotonic()
        try:
            async with asyncio.timeout(timeout):
                await waiter
        except BaseException as exc:
            if waiter.done() and not waiter.cancelled():
                self.give_slot(short)  # handed over just as we stopped waiting: pass it on
            else:
                waiter.cancel()
                if waiter in self._waiters[short]:
                    self._waiters[short].remove(waiter)
            if isinstance(exc, TimeoutError):
                message = f"no {self.name} slot came free within the request's time budget"
                raise self._refuse("queue_timeout", message) from exc
            raise

    def give_slot(self, short: bool = False) -> None:
        """Free a slot and hand the free slots on: to short work waiting first, then to long
        work within :meth:`_long_slots`."""
        self._free += 1
        self._running[short] -= 1
        self._dispatch()

    def _dispatch(self) -> None:
        for short in (True, False):
            line = self._waiters[short]
            while line and self._can_start(short):
                waiter = line.popleft()
                if not waiter.done():
                    self._hand(short)
                    waiter.set_result(None)
        if self._free > 0 and self._waiters[False] and self._recheck is None:
            # long work waits only for the reservation to lapse: look again then
            delay = max(0.0, self._short_seen + SHORT_DEMAND_S - time.monotonic())
            self._recheck = asyncio.get_running_loop().call_later(delay, self._rechecked)

    def _rechecked(self) -> None:
        self._recheck = None
        self._dispatch()


@dataclass(eq=False, slots=True)  # compared and hashed by identity
class _Worker:
    process: BaseProcess
    connection: Connection
    tasks: int = field(default=0)


class Lane(Gate):
    """A gate whose slots are worker processes running one task at a time."""

    def __init__(
        self,
        name: str,
        *,
        processes: int,
        queue: int,
        setting: str,
        settings: Settings,
        metrics: Metrics,
        short: ShortLine = ShortLine(),
    ) -> None:
        super().__init__(
            name, slots=processes, queue=queue, setting=setting, metrics=metrics, short=short
        )
        # One BLAS thread per worker: the matrices are small, and workers share the cores.
        for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(variable, "1")
        self._settings_json = settings.model_dump_json()
        self.niceness = compute_niceness(settings.worker_nice)  # of each process of the lane
        self._context = multiprocessing.get_context("spawn")
        self._idle: list[_Worker] = []
        self._busy: set[_Worker] = set()
        # One thread per process waits for its answer (a pipe read), so the loop never does.
        self._readers = ThreadPoolExecutor(processes, thread_name_prefix=f"gecko-{name}")
        self._closed = False

    def pids(self) -> dict[str, list[int]]:
        """Process ids of the lane's live workers: ``{"idle": [...], "busy": [...]}``."""
        return {
            "idle": [w.process.pid for w in self._idle if w.process.pid is not None],
            "busy": [w.process.pid for w in self._busy if w.process.pid is not None],
        }

    def _spawn(self) -> _Worker:
        ours, theirs = self._context.Pipe(duplex=True)
        process = self._context.Process(
            target=serve_tasks,
            args=(theirs, self._settings_json, os.getpid(), self.niceness),
            name=f"gecko-{self.name}",
            daemon=True,
        )
        process.start()
        if process.pid is not None:  # niced now, before its interpreter has imported much
            lower_priority(process.pid, self.niceness)
        theirs.close()  # only the child holds it now: its death reads as EOF on ours
        return _Worker(process, ours)

    @property
    def live_processes(self) -> int:
        """The lane's processes alive now (idle or busy; spawned on demand, so 0 at first)."""
        return len(self.process_ids())

    def process_ids(self) -> list[int]:
        """Ids of the lane's live processes, idle or busy."""
        workers = [*self._idle, *self._busy]
        return [w.process.pid for w in workers if w.process.pid and w.process.is_alive()]

    def _replace(self) -> None:
        """Start a fresh process in place of one that died under its task, so the next task
        does not wait for it to start (it stays idle until then). Started from a thread: a
        process start takes the loop's thread tens of ms, which /health would wait for."""
        if self._closed:
            return
        started = asyncio.get_running_loop().run_in_executor(None, self._spawn)
        started.add_done_callback(self._keep_idle)

    def _keep_idle(self, started: asyncio.Future[_Worker]) -> None:
        """Keep a process started for nobody in particular idle (killed if the lane closed)."""
        if started.cancelled():
            return
        error = started.exception()
        if error is not None:  # out of processes or memory: the next task tries again
            log.error("could not start a replacement %s process: %s", self.name, error)
        elif self._closed:
            self._discard(started.result(), kill=True)
        else:
            self._idle.append(started.result())

    async def _start_process(self) -> _Worker:
        """:meth:`_spawn` from a thread, off the event loop (see :meth:`_replace`); kept idle
        if the caller is cancelled meanwhile."""
        started = asyncio.get_running_loop().run_in_executor(None, self._spawn)
        try:
            worker = await asyncio.shield(started)
        except asyncio.CancelledError:
            started.add_done_callback(self._keep_idle)
            raise
        if self._closed:  # the lane shut down while the process started: it goes too
            self._discard(worker, kill=True)
            raise ApiError(503, "shutting_down", "the service is stopping; retry", None)
        return worker

    async def _take_worker(self) -> _Worker:
        while self._idle:
            worker = self._idle.pop()
            # An idle process never has anything to say: a readable pipe is its end (EOF).
            if worker.process.is_alive() and not worker.connection.poll():
                return worker
            log.error("an idle %s process died (exit code %s)", self.name, worker.process.exitcode)
            self._metrics.worker_restarts.inc()
            self._discard(worker)
        return await self._start_process()

    def _discard(self, worker: _Worker, *, kill: bool = False) -> None:
        if kill and worker.process.is_alive():
            worker.process.kill()
        worker.connection.close()
        # Reap it off the loop: a killed process exits at once, a dead one already has.
        try:
            self._readers.submit(worker.process.join, JOIN_KILLED_S)
        except RuntimeError:  # shutting down: the readers are gone
            worker.process.join(0.1)

    async def run(
        self,
        function: Callable[..., T],
        *args: Any,
        ticket: Ticket | None = None,
        start_by: float | None = None,
        finish_by: float | None = None,
        run_for_s: float | None = None,
        on_start: Callable[[], Awaitable[None] | None] | None = None,
    ) -> T:
        """``function(*args)`` in a worker process of this lane.

        ``ticket`` is the place :meth:`admit` gave (taken now when None: a 503 when full);
        ``start_by`` (monotonic s) the latest start (a 503 past it); ``finish_by`` (monotonic
        s) or ``run_for_s`` (s from the start) the latest answer (a 504 past it, the process
        killed). ``on_start`` is called (and awaited, when it is a coroutine function) when a
        process takes the task. Cancelling the calling task kills the process running it. A
        process that dies under the task is a 503 ``worker_lost``; exceptions the function
        raises are raised here.
        """
        ticket = ticket or self.admit()
        try:
            await self.take_slot(start_by, ticket.short)
            try:
                if on_start is not None:
                    started = on_start()
                    if inspect.isawaitable(started):  # a store write, say: off the loop
                        await started
                if run_for_s is not None:
                    finish_by = time.monotonic() + run_for_s
                return await self._call(function, args, finish_by)
            finally:
                self.give_slot(ticket.short)
        finally:
            ticket.release()

    async def _call(
        self, function: Callable[..., T], args: tuple[Any, ...], finish_by: float | None
    ) -> T:
        if self._closed:
            raise ApiError(503, "shutting_down", "the service is stopping; retry", None)
        worker = await self._take_worker()
        try:
            worker.connection.send((function, args))
        except (BrokenPipeError, OSError):  # died since: one fresh process, once
            self._metrics.worker_restarts.inc()
            self._discard(worker)
            worker = await self._start_process()
            worker.connection.send((function, args))
        self._busy.add(worker)
        loop = asyncio.get_running_loop()
        answer = loop.run_in_executor(self._readers, worker.connection.recv)
        answer.add_done_callback(_retrieve)  # a killed process's EOF is expected, not news
        healthy = lost = False
        try:
            timeout = None if finish_by is None else finish_by - time.monotonic()
            async with asyncio.timeout(timeout):
                kind, value = await asyncio.shield(answer)
            healthy = True
        except TimeoutError as exc:
            self._metrics.cancelled.labels(self.name, "timeout").inc()
            raise ApiError(504, "timeout", "no answer within the time budget", None) from exc
        except asyncio.CancelledError:
            self._metrics.cancelled.labels(self.name, "cancelled").inc()
            raise
        except (EOFError, OSError) as exc:
            worker.process.join(0.2)  # dead (its pipe closed): reaped at once, for its code
            log.error(
                "a %s process died under its task (exit code %s): %r",
                self.name,
                worker.process.exitcode,
                exc,
            )
            self._metrics.worker_restarts.inc()
            lost = True
            raise ApiError(
                503,
                "worker_lost",
                f"the {self.name} process running this request died; a fresh one has "
                "replaced it: retry",
                None,
                {"Retry-After": str(RETRY_AFTER_S[self.name])},
            ) from exc
        finally:
            self._busy.discard(worker)
            if healthy:
                worker.tasks += 1
                self._idle.append(worker)
            else:
                self._discard(worker, kill=True)
                if lost:
                    self._replace()
        if kind == "error":
            raise cast(BaseException, value)
        return cast(T, value)

    def shutdown(self) -> None:
        """Stop every process of the lane (running tasks fail with ``worker_lost``)."""
        self._closed = True
        for worker in [*self._idle, *self._busy]:
            self._discard(worker, kill=True)
        self._idle.clear()
        self._readers.shutdown(wait=False, cancel_futures=False)


def _retrieve(future: asyncio.Future[Any]) -> None:
    if not future.cancelled():
        future.exception()


class Lanes:
    """The lanes of one service worker: interactive work, background jobs, uploads."""

    def __init__(self, settings: Settings, metrics: Metrics) -> None:
        self.interactive = Lane(
            "interactive",
            processes=settings.worker_processes,
            queue=settings.interactive_queue,
            setting="GECKO_INTERACTIVE_QUEUE",
            settings=settings,
            metrics=metrics,
            short=ShortLine(
                settings.step_queue,
                "GECKO_STEP_QUEUE",
                # a process left to steps needs another for plans and jumps
                min(settings.step_processes, settings.worker_processes - 1),
            ),
        )
        self.jobs = Lane(
            "jobs",
            processes=settings.job_processes,
            queue=settings.job_queue,
            setting="GECKO_JOB_QUEUE",
            settings=settings,
            metrics=metrics,
        )
        self.uploads = Lane(
            "uploads",
            processes=UPLOAD_CONCURRENCY,
            queue=settings.upload_queue,
            setting="GECKO_UPLOAD_QUEUE",
            settings=settings,
            metrics=metrics,
        )
        metrics.worker_processes.set(settings.worker_processes)
        metrics.watch_gates(lambda: (self.interactive, self.jobs, self.uploads))

    def shutdown(self) -> None:
        self.interactive.shutdown()
        self.jobs.shutdown()
        self.uploads.shutdown()
