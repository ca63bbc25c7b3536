"""Reading a command's ``plan.json`` (``standstill plan``, ``commission plan``) back."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pneufdd.errors import InputError, describe

__all__ = ["read_plan_json"]


def read_plan_json(folder: Path, command: str) -> tuple[Path, Any]:
    """The parsed ``plan.json`` of ``command``: in the folder ``folder``, or the file itself.

    At most 4 MiB, JSON nested at most 64 levels (docs/limits.md); errors name ``--plan``.
    """
    from pneufdd.limits import check_json_depth, read_text_capped

    path = folder / "plan.json" if folder.is_dir() else folder
    if not path.is_file():
        raise InputError(describe("--plan", str(folder), f"a folder holding plan.json ({command})"))
    text = read_text_capped(path, "--plan")
    check_json_depth(text, f"--plan {path}")
    try:
        return path, json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(describe(f"--plan {path}", repr(exc), "a plan.json")) from exc
