"""Where files can be made: the one check that the CLI's output options, the results store
and a models directory share, made before anything is written."""

from __future__ import annotations

import os
from pathlib import Path


def existing_ancestor(path: str | Path) -> Path:
    """``path`` itself if it exists, else its nearest existing parent (where the missing
    directories would be created)."""
    path = Path(path)
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def can_make_files_in(directory: str | Path) -> bool:
    """Whether this process can make files in ``directory``, or create it when it is missing
    (its nearest existing parent is a directory it can write and enter)."""
    ancestor = existing_ancestor(directory)
    return ancestor.is_dir() and os.access(ancestor, os.W_OK | os.X_OK)
