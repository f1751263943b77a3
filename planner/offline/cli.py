"""``gecko-build-data``: build (or check) the cached offline data of characters."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from planner.character import (
    builtin_character_ids,
    character_spec_path,
    load_character,
    real_robot_ids,
)
from planner.offline.build import OfflineParams
from planner.offline.data import default_cache_dir, load_offline_data


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gecko-build-data",
        description="Build the offline data (workspaces, sample databases, COM constraints) "
        "of characters; cached results are reused.",
    )
    who = parser.add_mutually_exclusive_group()
    who.add_argument(
        "--character",
        action="append",
        metavar="ID",
        help="character id (repeatable); default: the built-in characters",
    )
    who.add_argument(
        "--all", action="store_true", help="built-in characters and the real robots available"
    )
    parser.add_argument(
        "--spec",
        action="append",
        type=Path,
        default=[],
        metavar="PATH",
        help="limb spec file of another character (repeatable)",
    )
    parser.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        help=f"cache directory (default: {default_cache_dir()})",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        help="workspace and COM samples (shorthand for both options below)",
    )
    parser.add_argument("--workspace-samples", type=int, default=None)
    parser.add_argument("--com-samples", type=int, default=None)
    parser.add_argument("--database-samples", type=int, default=None)
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    args = _parser().parse_args(argv)
    defaults = OfflineParams()
    workspace = args.workspace_samples or args.samples or defaults.workspace_samples
    com = args.com_samples or args.samples or defaults.com_samples
    database = args.database_samples or min(defaults.database_samples, workspace)
    try:
        params = OfflineParams(
            workspace_samples=workspace, database_samples=database, com_samples=com
        )
    except ValueError as exc:
        print(f"gecko-build-data: {exc}", file=sys.stderr)
        return 2
    if args.all:
        ids = list(builtin_character_ids() + real_robot_ids())
    elif args.character:
        ids = list(args.character)
    else:
        ids = [] if args.spec else list(builtin_character_ids())
    specs: list[Path] = []
    for cid in ids:
        try:
            specs.append(character_spec_path(cid))
        except KeyError as exc:
            print(f"gecko-build-data: {exc.args[0]}", file=sys.stderr)
            return 2
    specs.extend(args.spec)
    for spec in specs:
        start = time.perf_counter()
        character = load_character(spec)
        data = load_offline_data(
            character, args.cache_dir, seed=args.seed, params=params, progress=not args.no_progress
        )
        status = "built" if data.built else "cached"
        print(f"{character.id}: {status} in {time.perf_counter() - start:.2f} s -> {data.path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
