"""Regenerate (or check) the golden recordings of ``tests/isolation/golden/``.

Run from the repository root::

    .venv/bin/python tests/isolation/make_golden.py            # rewrite the golden files
    .venv/bin/python tests/isolation/make_golden.py --check    # exit 1 if they are stale

More in docs/modules.md, `tests/isolation/make_golden.py`.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from golden_config import GOLDEN_DIR, GOLDENS, Golden

from slipstack.launch.lockstep import run_launch_file
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import read_recording, same_output

__all__ = ["write_golden", "compare_recordings", "main"]


def write_golden(golden: Golden, path: Path) -> dict[str, int]:
    """Run ``golden``'s launch file in lock-step, recording every topic to ``path``; topic → frames."""
    path.unlink(missing_ok=True)
    run_launch_file(golden.launch, golden.launch_args(recording=path))
    counts: dict[str, int] = {}
    for frame in read_recording(path):
        counts[frame.topic] = counts.get(frame.topic, 0) + 1
    return counts


def compare_recordings(a: Path, b: Path) -> list[str]:
    """Differences between two recordings, frame by frame; [] if they are the same.

    Topic, log time, header seq and pub_ns and every integer, string and state must be
    equal; floats within ``same_output``'s stated tolerance (docs/portability.md §1).
    """
    fa, fb = list(read_recording(a, tolerant=False)), list(read_recording(b, tolerant=False))
    diffs = [f"{len(fa)} vs {len(fb)} frames"] if len(fa) != len(fb) else []
    for k, (x, y) in enumerate(zip(fa, fb)):
        if (x.topic, x.log_time_ns) != (y.topic, y.log_time_ns):
            diffs.append(f"frame {k}: {x.topic}@{x.log_time_ns} vs {y.topic}@{y.log_time_ns}")
            continue
        mx, my = decode(x.payload), decode(y.payload)
        differs = ("header.pub_ns" if mx.header.pub_ns != my.header.pub_ns
                   else same_output(mx, my, check_seq=True))
        if differs is not None:
            diffs.append(f"frame {k}: {x.topic}@{x.log_time_ns}: {differs}")
    return diffs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Recordings: " + ", ".join(g.name for g in GOLDENS))
    p.add_argument("--check", action="store_true",
                   help="regenerate into a temporary folder and compare with the committed files (exit 1 if stale)")
    p.add_argument("--out", type=Path, default=GOLDEN_DIR, help=f"output folder (default {GOLDEN_DIR})")
    p.add_argument("--only", action="append", choices=[g.name for g in GOLDENS], help="only this recording")
    args = p.parse_args(argv)
    chosen = [g for g in GOLDENS if not args.only or g.name in args.only]
    stale = 0
    with tempfile.TemporaryDirectory(prefix="golden-") as tmp:
        out = Path(tmp) if args.check else args.out
        for g in chosen:
            path = out / f"{g.name}.mcap"
            counts = write_golden(g, path)
            if args.check:
                diffs = compare_recordings(g.path, path) if g.path.exists() else [f"{g.path} missing"]
                stale += bool(diffs)
                print(f"{g.path}: {'STALE: ' + '; '.join(diffs[:3]) if diffs else 'fresh'}")
            else:
                topics = ", ".join(f"{t} {n}" for t, n in sorted(counts.items()))
                print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB): {topics}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
