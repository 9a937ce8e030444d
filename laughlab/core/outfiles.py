"""Writing output files so that a failed run leaves nothing half-written.

Every file is written under a temporary name (``.NAME.part``) and moved into
place only when the run succeeds (:meth:`Staging.commit`); :meth:`Staging.abort`
removes the temporary files.
"""
from __future__ import annotations

import os
from pathlib import Path


class Staging:
    """Temporary output files of one writer, committed or removed together."""

    def __init__(self) -> None:
        self.pending: dict[Path, Path] = {}

    def path(self, final: Path) -> Path:
        """The temporary path to write in place of ``final``."""
        final = Path(final)
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = final.with_name(f".{final.name}.part")
        self.pending[final] = tmp
        return tmp

    def commit(self) -> list[Path]:
        done = []
        for final, tmp in self.pending.items():
            os.replace(tmp, final)
            done.append(final)
        self.pending.clear()
        return done

    def abort(self) -> None:
        for tmp in self.pending.values():
            tmp.unlink(missing_ok=True)
        self.pending.clear()
