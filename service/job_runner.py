"""The jobs this service worker owns: started in the background lane, stopped on DELETE
(from any service worker, seen through the store) and reported interrupted when it stops."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from anyio import to_thread

from service.errors import ApiError
from service.jobs import Job, JobKind, JobStore, owner_id
from service.lanes import Lane, Ticket
from service.settings import JOB_POLL_S

log = logging.getLogger("gecko.jobs")
SHUTDOWN = "the service stopped while it ran (a restart); submit it again"
Work = Callable[["JobContext"], Awaitable[dict[str, Any]]]


class JobGone(Exception):
    """The job was cancelled (or interrupted) before a process took it."""


class JobContext:
    """What a job's work needs: its id, its place in the lane and the start hook."""

    def __init__(self, runner: JobRunner, job_id: str, ticket: Ticket) -> None:
        self.job_id = job_id
        self.ticket = ticket
        self._runner = runner

    async def on_start(self) -> None:
        """Mark the job running as a process takes it (raises :class:`JobGone` if it was
        cancelled while it waited). The store write runs in a thread: it may wait for the
        write lock (up to ``BUSY_TIMEOUT_S``) held by another process, a niced roadmap
        build writing its progress, say, and the event loop must not wait with it."""
        if not await to_thread.run_sync(self._runner.store.start, self.job_id):
            raise JobGone(self.job_id)


class JobRunner:
    """Runs this service worker's jobs and keeps the store's view of them honest."""

    def __init__(self, store: JobStore, lane: Lane) -> None:
        self.store = store
        self.lane = lane
        self.owner = owner_id()
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._poller: asyncio.Task[None] | None = None

    async def open(self) -> None:
        """Announce this owner and start watching for DELETEs of its jobs."""
        await to_thread.run_sync(self.store.heartbeat, self.owner)
        self._poller = asyncio.create_task(self._poll(), name="gecko-job-poller")

    async def submit(
        self, job_id: str, kind: JobKind, request: dict[str, Any], work: Work
    ) -> tuple[Job, bool]:
        """Queue a job (a 503 when the lane is full); ``(job, False)`` when one with this id
        is already active. ``work`` runs it and returns its result."""
        ticket = self.lane.admit()
        try:
            job, created = await to_thread.run_sync(
                self.store.submit, job_id, kind, request, self.owner
            )
        except BaseException:
            ticket.release()
            raise
        if not created:
            ticket.release()
            return job, False
        context = JobContext(self, job_id, ticket)
        task = asyncio.create_task(self._run(context, work), name=f"gecko-job-{job_id}")
        self._tasks[job_id] = task
        task.add_done_callback(lambda _: self._tasks.pop(job_id, None))
        return job, True

    async def _run(self, context: JobContext, work: Work) -> None:
        job_id = context.job_id
        try:
            result = await work(context)
        except (asyncio.CancelledError, JobGone):
            return  # a DELETE (the store says cancelled) or shutdown (release() says why)
        except ApiError as exc:
            await to_thread.run_sync(self.store.fail, job_id, f"{exc.code}: {exc.message}")
        except Exception as exc:
            log.exception("job %s failed", job_id)
            await to_thread.run_sync(self.store.fail, job_id, f"{type(exc).__name__}: {exc}")
        else:
            await to_thread.run_sync(self.store.finish, job_id, result)
        finally:
            context.ticket.release()

    async def cancel(self, job_id: str) -> Job | None:
        """Cancel a job wherever it runs. This service worker stops its own at once (its
        process killed and its slot freed before this returns); another one within
        ``JOB_POLL_S``."""
        job = await to_thread.run_sync(self.store.cancel, job_id)
        task = self._tasks.get(job_id)
        if task is not None and job is not None and job.state == "cancelled":
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
        return job

    async def _poll(self) -> None:
        while True:
            await asyncio.sleep(JOB_POLL_S)
            try:
                await to_thread.run_sync(self.store.heartbeat, self.owner)
                states = await to_thread.run_sync(self.store.states, list(self._tasks))
            except Exception as exc:  # a busy or broken store: try again next time
                log.warning("job store poll failed: %s: %s", type(exc).__name__, exc)
                continue
            for job_id, state in states.items():
                task = self._tasks.get(job_id)
                if task is not None and state not in ("queued", "running"):
                    log.info("job %s is %s: stopping it", job_id, state)
                    task.cancel()

    async def close(self) -> None:
        """Stop every job of this owner; the store reports them interrupted."""
        if self._poller is not None:
            self._poller.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._poller
        tasks = list(self._tasks.values())
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await to_thread.run_sync(self.store.release, self.owner, SHUTDOWN)
