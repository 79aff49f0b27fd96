"""Reading monitor recordings (:mod:`adapters.mcap_recorder`): every recorded window with its
result, alert and the configuration it was analysed with, in time order.

Files are finished ``.mcap`` files (a directory stands for its ``*.mcap`` files in name order,
which is time order for one instance).  A ``.part`` file or a file without a summary (cut short
by a crash) is an error that says to run ``loopwatch recover`` first.
"""

from __future__ import annotations

import bisect
import json
import logging
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from . import mcap_codec as codec
from .errors import AdapterError

log = logging.getLogger("loopwatch.replay")

__all__ = ["RecordedGroup", "RecordingReadError", "recording_files", "read_recording", "count_windows"]


class RecordingReadError(AdapterError):
    """A recording cannot be read; the message names the file and what to do."""


@dataclass(frozen=True)
class RecordedGroup:
    """One recorded window: samples, result message, alert message (or None), and the loop's
    config and the run config in force when it was recorded."""

    source: str
    window: codec.WindowRecord
    result: dict
    alert: dict | None
    config: dict
    run: dict

    @property
    def loop_id(self) -> str:
        return self.window.loop_id


def recording_files(paths: Sequence[str | Path]) -> list[Path]:
    """The finished recording files named by ``paths`` (files, or directories of ``*.mcap``)."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(p.glob("*.mcap"))
            if not found:
                parts = sorted(p.glob("*.mcap.part"))
                hint = f" ({len(parts)} unfinished .part file(s): `loopwatch recover` them)" if parts else ""
                raise RecordingReadError(f"{p}: no .mcap recordings in this directory{hint}")
            out += found
        elif p.is_file():
            if p.name.endswith(".part"):
                raise RecordingReadError(f"{p}: an unfinished recording; run `loopwatch recover {p}` first")
            out.append(p)
        else:
            raise RecordingReadError(f"{p}: no such file or directory")
    return out


def _open(path: Path):
    fh = path.open("rb")
    try:
        reader = make_reader(fh)
        summary = reader.get_summary()
    except (McapError, ValueError, OSError) as exc:
        fh.close()
        raise RecordingReadError(f"{path}: not a finished MCAP file ({type(exc).__name__}: {exc}); "
                                 f"if it was cut short, run `loopwatch recover {path}`") from None
    if summary is None:
        fh.close()
        raise RecordingReadError(f"{path}: no summary section (cut short?); run `loopwatch recover {path}`")
    return fh, reader, summary


def _loop_topics(summary, loops: set[str] | None, kinds: Iterable[str]) -> list[str]:
    kinds = set(kinds)
    out = []
    for ch in summary.channels.values():
        parsed = codec.parse_topic(ch.topic)
        if parsed and parsed[1] in kinds and (loops is None or parsed[0] in loops):
            out.append(ch.topic)
    return out


def count_windows(paths: Sequence[str | Path], loops: Iterable[str] | None = None) -> int:
    """Windows recorded in ``paths`` (for ``loops``), from the files' summaries (no time filter)."""
    want = None if loops is None else set(loops)
    n = 0
    for path in recording_files(paths):
        fh, _, summary = _open(path)
        with fh:
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            for cid, ch in summary.channels.items():
                parsed = codec.parse_topic(ch.topic)
                if parsed and parsed[1] == "window" and (want is None or parsed[0] in want):
                    n += counts.get(cid, 0)
    return n


def read_recording(paths: Sequence[str | Path], *, loops: Iterable[str] | None = None,
                   start_ns: int | None = None, end_ns: int | None = None) -> Iterator[RecordedGroup]:
    """Every recorded window in ``paths``, in time order per file and files in name order.

    Parameters
    ----------
    loops : only these loop ids (default all).
    start_ns, end_ns : only windows whose last sample time (ns) is in ``[start_ns, end_ns]``.
    """
    want = None if loops is None else set(loops)
    for path in recording_files(paths):
        fh, reader, summary = _open(path)
        with fh:
            yield from _read_file(path, reader, summary, want, start_ns, end_ns)


def _read_file(path, reader, summary, want, start_ns, end_ns) -> Iterator[RecordedGroup]:
    # configs first, without the time filter (a loop's config precedes its first window in the file)
    runs: list[tuple[int, dict]] = []
    configs: dict[str, tuple[list[int], list[dict]]] = {}
    cfg_topics = _loop_topics(summary, want, ("config",))
    for _, ch, msg in reader.iter_messages(topics=[codec.RUN_TOPIC, *cfg_topics]):
        body = _json(path, ch.topic, msg.data)
        if ch.topic == codec.RUN_TOPIC:
            runs.append((msg.log_time, body))
        else:
            times, bodies = configs.setdefault(body.get("loop", ""), ([], []))
            times.append(msg.log_time)
            bodies.append(body)
    run = runs[-1][1] if runs else {}
    topics = _loop_topics(summary, want, ("window", "result", "alert"))
    if not topics:
        return
    kw = {}
    if start_ns is not None:
        kw["starting_at"] = int(start_ns)
    if end_ns is not None:
        kw["ending_at"] = int(end_ns)
    pending: dict[tuple[str, int], dict] = {}
    current = None

    def flush():
        for (loop, seq), parts in sorted(pending.items(), key=lambda kv: kv[1]["order"]):
            if "window" not in parts or "result" not in parts:
                # a recovered file can end between a window's messages (they may straddle chunks)
                log.warning("%s: window %d of loop %s lacks its %s message; skipped", path, seq, loop,
                            "window" if "window" not in parts else "result")
                continue
            times, bodies = configs.get(loop, ([], []))
            i = bisect.bisect_right(times, parts["log_time"]) - 1
            if i < 0:
                raise RecordingReadError(f"{path}: loop {loop} has no config message before window {seq}")
            yield RecordedGroup(str(path), codec.decode_window(parts["window"], parts["log_time"]),
                                parts["result"], parts.get("alert"), bodies[i], run)
        pending.clear()

    for order, (_, ch, msg) in enumerate(reader.iter_messages(topics=topics, **kw)):
        if current is not None and msg.log_time != current:
            yield from flush()
        current = msg.log_time
        loop, kind = codec.parse_topic(ch.topic)
        body = _json(path, ch.topic, msg.data)
        parts = pending.setdefault((loop, int(body.get("seq", -1))), {"order": order, "log_time": msg.log_time})
        parts[kind] = body
    yield from flush()


def _json(path, topic: str, data: bytes) -> dict:
    try:
        body = json.loads(data)
    except ValueError as exc:
        raise RecordingReadError(f"{path}, topic {topic}: message is not JSON ({exc})") from None
    if not isinstance(body, dict):
        raise RecordingReadError(f"{path}, topic {topic}: message is not a JSON object")
    return body
