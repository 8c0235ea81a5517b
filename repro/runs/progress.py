"""Progress bars on stderr for anything that takes seconds (silent when REPRO_QUIET is set)."""

from __future__ import annotations

import os
from typing import Iterable, TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")


def progress(it: Iterable[T], desc: str, total: int | None = None) -> Iterable[T]:
    disable = bool(os.environ.get("REPRO_QUIET"))
    return tqdm(it, desc=desc, total=total, disable=disable, leave=False, dynamic_ncols=True)
