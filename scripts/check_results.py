"""CI guard on the stored results (issue 51 item 6): no file under benchmarks/results over
1 MiB, and the folder's total within its cap, so that the clone stops growing by tens of MB
a study. New runs are stored as compact digests (engine.io.digest) with their full files
outside git.

The cap is the total at 25c0461 (277.4 MiB, 1,484 files, when the rule was made) plus a
growth budget of 20 MiB. Run by scripts/test.sh (and so by .ci/run):

    python scripts/check_results.py
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = "benchmarks/results"
MAX_FILE = 1 << 20  # bytes
#: 290,880,513 bytes at 25c0461 plus 20 MiB.
MAX_TOTAL = 290_880_513 + 20 * (1 << 20)


def tracked() -> list[Path]:
    out = subprocess.run(
        ["git", "ls-files", "-z", RESULTS], cwd=ROOT, capture_output=True, check=True
    ).stdout
    return [ROOT / p for p in out.decode().split("\0") if p]


def main() -> int:
    files = [p for p in tracked() if p.is_file()]
    big = [(p.stat().st_size, p) for p in files if p.stat().st_size > MAX_FILE]
    total = sum(p.stat().st_size for p in files)
    bad = False
    for size, p in sorted(big, reverse=True):
        print(
            f"check_results: {p.relative_to(ROOT)} is {size / (1 << 20):.2f} MiB, over the "
            f"{MAX_FILE / (1 << 20):.0f} MiB a stored result may be: store a digest "
            "(engine.io.digest) and keep the full file outside git",
            file=sys.stderr,
        )
        bad = True
    if total > MAX_TOTAL:
        print(
            f"check_results: {RESULTS} holds {total / (1 << 20):.1f} MiB, over its cap of "
            f"{MAX_TOTAL / (1 << 20):.1f} MiB (scripts/check_results.py)",
            file=sys.stderr,
        )
        bad = True
    if not bad:
        print(
            f"check_results: {len(files)} files, {total / (1 << 20):.1f} of "
            f"{MAX_TOTAL / (1 << 20):.1f} MiB, none over {MAX_FILE / (1 << 20):.0f} MiB"
        )
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
