"""Output folders: created and checked writable before any long job starts."""

from __future__ import annotations

from pathlib import Path

__all__ = ["ensure_writable"]


def ensure_writable(path: Path) -> None:
    """Create the folder ``path`` if needed and check a file can be written there.

    Raises ``OSError`` (the operating system's reason) when it cannot.
    """
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    probe = path / ".write-test"
    probe.write_text("")
    probe.unlink()
