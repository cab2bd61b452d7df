"""The main job behind ``make demo`` / ``vmt demo``."""

from __future__ import annotations

from pathlib import Path


def main_job(out: str = "out", seed: int = 2026) -> int:
    """Run the most complete end-to-end story vmt has; return an exit code."""
    from core.iso import TWENTY_ONE

    Path(out).mkdir(parents=True, exist_ok=True)
    print(f"vmt demo: the 21 errors of three linear axes: {' '.join(TWENTY_ONE)}")
    return 0
