"""Stored results: every plan, Twister step and jump answer kept on disk under a content id.

The id is a hash of the kind, the request (every field, defaults filled in, the seed used)
and the code version, so the same request with the same seed on the same code gets the same
id. Each result is ``<id>.json`` ({"kind", "id", "request", "response"}) with a small
``<id>.meta.json`` beside it for listings. Both are written to temporary files and renamed
into place, so readers never see half a file and several service workers may share the
directory. The store is bounded by a count and a byte size: after each write the least
recently used results (by modification time; a read touches it) are removed until both
bounds hold (down to ``LOW_WATER`` of them, so that a full store is not scanned on every
write; whether a bound is passed is read from one directory listing).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import tempfile
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from service import __version__
from service.files import is_temporary
from service.settings import REPO_ROOT

log = logging.getLogger("gecko.results")

Kind = Literal["plan", "step", "jump"]
KINDS: tuple[Kind, ...] = ("plan", "step", "jump")
ID_LENGTH = 32
LOW_WATER = 0.95  # a write past a bound evicts down to this share of the bounds
CODE_PACKAGES = ("trajectory", "planner", "service")


@lru_cache(maxsize=1)
def code_version() -> str:
    """``<version>+<hash of the Python sources of trajectory, planner and service>``.

    Any change to the code that computes answers gives new result ids.
    """
    digest = hashlib.sha256()
    for package in CODE_PACKAGES:
        for path in sorted((REPO_ROOT / package).rglob("*.py")):
            digest.update(path.relative_to(REPO_ROOT).as_posix().encode())
            digest.update(path.read_bytes())
    return f"{__version__}+{digest.hexdigest()[:12]}"


def result_id(kind: Kind, request: dict[str, Any], seed: int) -> str:
    """Content id of a result: kind, canonical request JSON with the seed used, code version."""
    canonical = json.dumps({**request, "seed": seed}, sort_keys=True, separators=(",", ":"))
    text = f"{kind}\n{code_version()}\n{canonical}"
    return hashlib.sha256(text.encode()).hexdigest()[:ID_LENGTH]


def stored_result(
    kind: Kind, request: dict[str, Any], seed: int, answer: dict[str, Any]
) -> tuple[StoredResult, dict[str, Any]]:
    """An answer ready to keep: the stored result (the answer with its content ``id``) and
    its summary for listings. ``request`` is the request's JSON form (defaults filled in)."""
    rid = result_id(kind, request, seed)
    response = {**answer, "id": rid}
    keyframes = response.get("keyframes") or []
    summary = {
        "character": request.get("character"),
        "scene": request.get("scene"),
        "status": response.get("status"),
        "seed": seed,
        "keyframes": len(keyframes),
        "duration": keyframes[-1]["t"] if keyframes else 0.0,
    }
    return StoredResult(kind, rid, {**request, "seed": seed}, response), summary


def is_result_id(text: str) -> bool:
    """True for a well-formed id (lower-case hexadecimal of the right length)."""
    return len(text) == ID_LENGTH and all(c in "0123456789abcdef" for c in text)


@dataclass(frozen=True, slots=True)
class StoredResult:
    """A stored answer: its kind and id, the request (with the seed used), the response."""

    kind: Kind
    id: str
    request: dict[str, Any]
    response: dict[str, Any]


class ResultStore:
    """Results on disk under ``directory``, at most ``max_count`` and ``max_bytes``."""

    def __init__(self, directory: Path, *, max_count: int, max_bytes: int) -> None:
        if max_count < 1 or max_bytes < 1:
            raise ValueError("max_count and max_bytes must be positive")
        self.directory = directory
        self.max_count = max_count
        self.max_bytes = max_bytes
        self.directory.mkdir(parents=True, exist_ok=True)
        # bytes of each stored file by name, as this process last saw it: a file is written
        # once under its content id, so after a first stat its size is known
        self._sizes: dict[str, int] = {}

    def _paths(self, rid: str) -> tuple[Path, Path]:
        return self.directory / f"{rid}.json", self.directory / f"{rid}.meta.json"

    def put(
        self, result: StoredResult, summary: dict[str, Any], *, response_json: bytes | None = None
    ) -> bool:
        """Store a result (replacing one with the same id), then evict; False if it alone
        is larger than the byte bound (then it is not kept). ``response_json``: the response
        already serialised as JSON (the route's body, of the same value as
        ``result.response``), written as it is: the standard library's encoder takes 2.7 ms
        for a Twister step's 60 kB of numbers, a twentieth of the step."""
        head = _compact({"kind": result.kind, "id": result.id, "request": result.request})
        if response_json is None:
            response_json = _compact(result.response)
        body = b"".join((head[:-1], b',"response":', response_json, b"}"))
        meta = _compact({"kind": result.kind, "id": result.id, "stored_at": time.time(), **summary})
        if len(body) + len(meta) > self.max_bytes:
            log.warning("result %s (%d bytes) exceeds the store bound", result.id, len(body))
            return False
        path, meta_path = self._paths(result.id)
        _atomic_write(meta_path, meta)
        _atomic_write(path, body)
        self._sizes[meta_path.name] = len(meta)
        self._sizes[path.name] = len(body)
        if self._over_bounds():
            self.evict(keep=result.id, low_water=True)
        return True

    def _over_bounds(self) -> bool:
        """Whether the stored results may exceed a bound: one directory listing, and a stat
        only of the files this process has not seen yet (the full, ordered scan of
        :meth:`evict` runs only then, not after every write)."""
        count = total = 0
        sizes: dict[str, int] = {}
        try:
            with os.scandir(self.directory) as entries:
                for entry in entries:
                    name = entry.name
                    if not name.endswith(".json") or is_temporary(name):
                        continue
                    size = self._sizes.get(name)
                    if size is None:
                        try:
                            size = entry.stat().st_size
                        except OSError:
                            continue
                    sizes[name] = size
                    total += size
                    count += not name.endswith(".meta.json")
        except OSError:
            return True
        self._sizes = sizes
        return count > self.max_count or total > self.max_bytes

    def get(self, rid: str, kind: Kind | None = None) -> StoredResult | None:
        """The result with this id (of this kind, when given), or None; marks it as used."""
        if not is_result_id(rid):
            return None
        path, meta_path = self._paths(rid)
        try:
            stored = json.loads(path.read_bytes())
        except (OSError, ValueError):
            return None
        if kind is not None and stored.get("kind") != kind:
            return None
        now = time.time()
        for touched in (path, meta_path):
            with contextlib.suppress(OSError):
                os.utime(touched, (now, now))
        return StoredResult(stored["kind"], stored["id"], stored["request"], stored["response"])

    def summaries(self, limit: int, kind: Kind | None = None) -> list[dict[str, Any]]:
        """Summaries of the most recently used results, newest first, at most ``limit``."""
        entries = []
        for meta_path in self.directory.glob("*.meta.json"):
            if is_temporary(meta_path.name):
                continue
            try:
                entries.append((meta_path.stat().st_mtime, meta_path))
            except OSError:
                continue
        entries.sort(key=lambda entry: (-entry[0], entry[1].name))
        out: list[dict[str, Any]] = []
        for _, meta_path in entries:
            if len(out) >= limit:
                break
            try:
                meta = json.loads(meta_path.read_bytes())
            except (OSError, ValueError):
                continue
            if kind is None or meta.get("kind") == kind:
                out.append(meta)
        return out

    def evict(self, keep: str | None = None, *, low_water: bool = False) -> int:
        """Remove least recently used results until the count and byte bounds hold; returns
        how many were removed. ``keep`` is never removed. With ``low_water`` (a write past a
        bound), down to ``LOW_WATER`` of the bounds, so that a full store is not scanned
        again on every write."""
        max_count, max_bytes = self.max_count, self.max_bytes
        if low_water:
            max_count -= int(max_count * (1.0 - LOW_WATER))
            max_bytes -= int(max_bytes * (1.0 - LOW_WATER))
        entries = []
        for path in self.directory.glob("*.json"):
            if path.name.endswith(".meta.json") or is_temporary(path.name):
                continue
            meta_path = path.with_name(f"{path.stem}.meta.json")
            try:
                size = path.stat().st_size + (meta_path.stat().st_size if meta_path.exists() else 0)
                entries.append((path.stat().st_mtime, path.stem, size))
            except OSError:
                continue
        entries.sort()
        count = len(entries)
        total = sum(size for _, _, size in entries)
        removed = 0
        for _, rid, size in entries:
            if count <= max_count and total <= max_bytes:
                break
            if rid == keep:
                continue
            for path in self._paths(rid):
                path.unlink(missing_ok=True)
            count -= 1
            total -= size
            removed += 1
        return removed


def _compact(value: Any) -> bytes:
    """``value`` as JSON without spaces, UTF-8."""
    return json.dumps(value, separators=(",", ":")).encode()


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".json")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
