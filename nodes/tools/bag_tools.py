"""``slipstack bag record | play | info | export``: recordings as MCAP files.

    slipstack bag record [-a | TOPIC ...] [-o PATH] [--run-dir D] [--duration S]
    slipstack bag play PATH [--rate R] [--loop] [--topics T ...] [--start-offset S] [--restamp]
    slipstack bag info PATH
    slipstack bag export PATH -o OUT.mcap|OUT.jsonl [--to mcap-json|jsonl|ros2]   (other suffixes refused)

The file layout (encodings, clocks, chunking) is described in ``nodes/recording/bag_io.py``.
"""

from __future__ import annotations

import argparse
import sys
from datetime import datetime
from pathlib import Path

from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.graph_info import RUN_DIR_HELP

__all__ = ["add_parser", "format_info", "EXPORT_FORMATS"]

EXPORT_SUFFIXES = {".mcap": "mcap-json", ".jsonl": "jsonl"}
EXPORT_FORMATS = (*EXPORT_SUFFIXES.values(), "ros2")  # nodes/recording/export.py's, without importing mcap for --help


def add_parser(sub: argparse._SubParsersAction) -> None:
    bag = sub.add_parser("bag", help="record, play, inspect and export recordings (MCAP)",
                         description="Recordings of the bus as MCAP files (msgpack payloads, chunked, indexed).")
    verbs = bag.add_subparsers(dest="verb", required=True, metavar="VERB")

    rec = verbs.add_parser("record", help="record topics of the running graph",
                           description="Record topics of the running graph until Ctrl-C/SIGTERM or --duration. "
                                       "Prints the output path. Default output: runs/<YYYYmmdd-HHMMSS>.mcap.")
    rec.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to record")
    rec.add_argument("-a", "--all", action="store_true", help="record every topic (also ones appearing later)")
    rec.add_argument("-o", "--output", help="output .mcap file")
    rec.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    rec.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    rec.set_defaults(func=_main_record)

    pl = verbs.add_parser("play", help="publish a recording on the bus",
                          description="Publish a recording with its original timing (scaled by --rate). "
                                      "Running nodes subscribed to a played topic receive it through their inject "
                                      "endpoints. Without --restamp the recorded headers go out unchanged; with it, "
                                      "stamp_ns, pub_ns and sources are shifted so the first frame is stamped now.")
    pl.add_argument("path", help="recording (.mcap)")
    pl.add_argument("--rate", type=float, default=1.0, help="speed factor (default 1)")
    pl.add_argument("--loop", action="store_true", help="start over at the end")
    pl.add_argument("--topics", nargs="+", metavar="T", help="topics to play (default: all but diagnostics)")
    pl.add_argument("--start-offset", type=float, default=0.0, metavar="S", help="skip the first S seconds")
    pl.add_argument("--restamp", action="store_true", help="shift header stamps to the current time")
    pl.add_argument("--endpoint", help="endpoint to bind (default ipc://<run dir>/bag_play-<pid>.pub)")
    pl.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    pl.set_defaults(func=_main_play)

    info = verbs.add_parser("info", help="summarise a recording",
                            description="Topics, counts, rates, sequence gaps and damage of a recording; reads "
                                        "unfinished (killed) and damaged files as far as they go.")
    info.add_argument("path", help="recording (.mcap)")
    info.set_defaults(func=_main_info)

    ex = verbs.add_parser("export", help="export to JSON (Foxglove-readable MCAP or JSON lines) or ROS 2",
                          description="Export a recording as MCAP with JSON messages and JSON Schemas (opens in "
                                      "Foxglove: the pad as the image /pad/pressure, times on the wall clock, "
                                      "header.stamp_ns kept on the monotonic clock), as JSON lines, or with --to "
                                      "ros2 as rosbag2 writes MCAP (CDR, ros2msg schemas: `ros2 bag`, Foxglove and "
                                      "PlotJuggler read it; needs the ros2 extra; docs/ros2.md). Without --to the "
                                      "format follows the output's suffix; "
                                      "other suffixes (.csv ...) are refused: for CSV use "
                                      "`slipstack topic echo TOPIC --csv` on a played recording. An existing OUT is "
                                      "refused unless --overwrite. A damaged recording is exported as far as it can be "
                                      "read, and the command says what was damaged and exits 1.")
    ex.add_argument("path", help="recording (.mcap)")
    ex.add_argument("-o", "--output", required=True, help="OUT.mcap or OUT.jsonl")
    ex.add_argument("--to", "--format", dest="format", choices=EXPORT_FORMATS,
                    help="mcap-json, jsonl or ros2; default: from the output suffix (.mcap, .jsonl)")
    ex.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    ex.set_defaults(func=_main_export)


def _main_record(args: argparse.Namespace) -> int:
    from slipstack.nodes.recording.recorder import default_output_path, record

    if args.all == bool(args.topics):
        raise ConfigError("give either -a (all topics) or TOPIC names")
    out = Path(args.output) if args.output else default_output_path()
    record(out, None if args.all else list(args.topics), args.run_dir, args.duration)
    return 0


def _main_play(args: argparse.Namespace) -> int:
    if not args.rate > 0:  # before anything is read or connected
        raise ConfigError(f"--rate must be > 0 (a speed factor: 1 = as recorded, 2 = twice as fast), got {args.rate:g}")
    from slipstack.nodes.recording.player import play

    play(args.path, topics=args.topics, rate=args.rate, loop=args.loop, start_offset_s=args.start_offset,
         restamp_stamps=args.restamp, endpoint=args.endpoint, run_dir=args.run_dir)
    return 0


def _fmt_time(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9).isoformat(sep=" ", timespec="milliseconds")


def format_info(info) -> str:  # noqa: ANN001 — a bag_io.RecordingInfo
    """The text of ``slipstack bag info``."""
    lines = [
        f"path:       {info.path}",
        f"size:       {info.size_bytes / 1e6:.3f} MB",
        f"finished:   {'yes (summary and indexes written)' if info.finished else 'NO — unfinished; read up to the last intact chunk'}",
    ]
    if info.ros2:
        lines.append("format:     ros2 (rosbag2 MCAP): each topic below is /slipstack/<topic> with its …/info, "
                     "counted as the bus frames they were made of")
    lines += [f"not read:   {topic} ({why})" for topic, why in sorted(info.left_out.items())]
    if info.damage:
        lines.append(f"damage:     {info.damage}")
    lines += [
        f"chunks:     {info.chunk_count}",
        f"messages:   {info.message_count}",
        f"duration:   {info.duration_s:.3f} s",
    ]
    if info.message_count and info.simulated_clock:
        lines += [f"start:      {info.start_ns / 1e9:.3f} s, simulated clock (lock-step: from the run's start, "
                  f"no date) ({info.start_ns})",
                  f"end:        {info.end_ns / 1e9:.3f} s, simulated clock ({info.end_ns})"]
    elif info.message_count:
        lines += [f"start:      {_fmt_time(info.start_ns)} ({info.start_ns})",
                  f"end:        {_fmt_time(info.end_ns)} ({info.end_ns})"]
    lines.append("topics:")
    width = max((len(t) for t in info.topics), default=5)
    for t in info.topics.values():
        lines.append(f"  {t.topic:<{width}}  {t.count:>8} msgs  {t.rate_hz:9.1f} Hz  seq {t.first_seq}..{t.last_seq}  "
                     f"gaps {t.seq_gaps:<5} missing {_missing(t):<8} {', '.join(t.types)}")
    if any(t.missing is None for t in info.topics.values()):
        lines.append("missing ?: not known: the recorder did not close the file (killed, or an older recording); "
                     "frames sent after its end are not counted")
    if any(not t.loss.get("exact", True) for t in info.topics.values()):
        lines.append("missing ≥N: at least; a publisher's last diagnostics (what it sent) never reached the recorder")
    return "\n".join(lines)


def _missing(t) -> str:  # noqa: ANN001 — a bag_io.TopicInfo
    """Frames sent and not in the file: ``0``, ``N`` (exact), ``≥N`` (at least) or ``?`` (not known)."""
    if t.missing is None:
        return "?"
    return f"{'' if t.loss.get('exact', True) else '≥'}{t.missing}"


def _main_info(args: argparse.Namespace) -> int:
    from slipstack.lib.progress import file_progress
    from slipstack.nodes.recording.bag_io import recording_info

    with file_progress(args.path, "bag info") as progress:
        info = recording_info(args.path, progress=progress)
    print(format_info(info))
    return 0


def _main_export(args: argparse.Namespace) -> int:
    from slipstack.nodes.recording.export import export_recording

    fmt = args.format or EXPORT_SUFFIXES.get(Path(args.output).suffix.lower())
    if fmt is None:
        raise ConfigError(f"cannot tell the export format from {args.output!r}: name it OUT.mcap (MCAP with JSON, "
                          "for Foxglove) or OUT.jsonl (JSON lines), or give --to (ros2: MCAP as rosbag2 writes it); CSV is not an export format")
    from slipstack.lib.progress import file_progress

    damage: list[str] = []
    with file_progress(args.path, "bag export") as progress:
        n = export_recording(args.path, args.output, fmt, progress=progress, force=args.overwrite, on_damage=damage.append)
    print(f"wrote {args.output}: {n} messages ({fmt})")
    if damage:
        print(f"slipstack bag export: {args.path} is damaged ({damage[0]}); {args.output} holds the {n} messages that "
              "could be read. `slipstack bag info` shows what is left", file=sys.stderr)
        return 1
    return 0
