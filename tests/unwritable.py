"""Paths in which nothing can be created, for the tests of unwritable caches and outputs."""

from __future__ import annotations

from pathlib import Path

import pytest

#: how a path can be unwritable: the first holds even for root, the second only for other users
WAYS = ["under a file", "read-only folder"]


def unwritable(tmp_path: Path, how: str) -> Path:
    """A folder path in which nothing can be created: under a regular file (so even for root),
    or a folder of mode 0555 (skipped where this user, root, writes there all the same)."""
    if how == "under a file":
        (tmp_path / "file").write_text("")
        return tmp_path / "file" / "sub"
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        (folder / "probe").write_text("")
    except OSError:
        return folder
    pytest.skip("this user (root?) writes into a folder of mode 0555: 'under a file' covers the case")
