"""Recording of the monitor to MCAP: a window sink with rotation, retention, flushing and recovery.

:class:`McapRecorder` is a :class:`~service.ports.WindowSink` (it also gets each window's alert
transition, so it need not be an alert sink).  ``on_window`` only hands the window to a writer
thread through a bounded queue (a full queue drops and counts, it never blocks the monitor); the
writer thread encodes (:mod:`adapters.mcap_codec`) and writes zstd-compressed chunks.

Files: ``{dir}/{instance}-{UTC start}-{n}.mcap``, written as ``….mcap.part`` (locked with
``flock`` while open) and renamed when finished, so readers only ever see finished files.
A file rolls over when it reaches ``rotate_bytes`` or is ``rotate_s`` old (wall time); then the
oldest finished files of the instance are deleted while the total exceeds ``retention_bytes`` or
they are older than ``retention_s``.  The chunk in progress is flushed every ``flush_s``, which
bounds what a crash can lose: :func:`recover_file` rewrites every complete record of a truncated
file into a finished one, and the recorder does so on start for its instance's leftover ``.part``
files that no live process holds.

Any ``OSError`` (full disk, unwritable directory) degrades the recorder: it logs once, reports
``state = "degraded"`` and the error in :meth:`McapRecorder.status`, drops (and counts) windows,
and retries every ``retry_s``.  Monitoring never stops for it.
"""

from __future__ import annotations

import fcntl
import logging
import os
import queue
import re
import struct
import threading
import time
import uuid
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from mcap.exceptions import InvalidMagic, McapError
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from . import mcap_codec as codec
from .errors import AdapterError

__all__ = ["McapRecorder", "RecoveryResult", "recover_file", "recover_leftovers", "RecordingError"]

log = logging.getLogger("loopwatch.recording")

LIBRARY = "loopwatch"
_STOP = object()


class RecordingError(AdapterError):
    """A recording file cannot be read or recovered; the message names the file."""


@dataclass(frozen=True)
class RecoveryResult:
    source: str
    target: str
    messages: int
    truncated: bool
    error: str | None = None


def _lock(fh) -> bool:
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:
        return False


def recover_file(src: str | Path, dst: str | Path | None = None) -> RecoveryResult:
    """Rewrite every complete record of ``src`` (e.g. cut short by a crash) into a finished MCAP file.

    ``dst`` defaults to ``src`` without ``.part`` (or with ``.recovered.mcap`` when ``src`` is a
    finished ``.mcap``).  Reads sequentially and stops at the first incomplete or corrupt record
    (a chunk whose CRC does not match is dropped).  Raises :class:`RecordingError` when ``src``
    is not an MCAP file at all.
    """
    src = Path(src)
    if dst is None:
        dst = src.with_suffix("") if src.suffix == ".part" else src.with_name(src.stem + ".recovered.mcap")
    dst = Path(dst)
    if dst.resolve() == src.resolve():
        raise RecordingError(f"{src}: recovering into the same file would destroy it; give another target")
    tmp = dst.with_name(dst.name + ".tmp")
    try:
        fin = src.open("rb")
    except OSError as exc:
        raise RecordingError(f"{src}: cannot open ({exc.strerror or exc})") from None
    with fin:
        try:
            StreamReader(fin).records.__next__()   # the magic and the header
        except (InvalidMagic, McapError, StopIteration) as exc:
            raise RecordingError(f"{src}: not an MCAP file ({type(exc).__name__})") from None
        fin.seek(0)
        return _rewrite(src, fin, tmp, dst)


def _rewrite(src: Path, fin, tmp: Path, dst: Path) -> RecoveryResult:
    n, truncated, err = 0, False, None
    with tmp.open("wb") as fout:
        w = Writer(fout, compression=CompressionType.ZSTD)
        w.start(library=f"{LIBRARY} (recovered)")
        smap, cmap = {0: 0}, {}
        records = StreamReader(fin, validate_crcs=True, record_size_limit=1 << 30).records
        try:
            for rec in records:
                if isinstance(rec, Schema) and rec.id not in smap:
                    smap[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
                elif isinstance(rec, Channel) and rec.id not in cmap:
                    cmap[rec.id] = w.register_channel(rec.topic, rec.message_encoding, smap.get(rec.schema_id, 0),
                                                      rec.metadata)
                elif isinstance(rec, Message) and rec.channel_id in cmap:
                    w.add_message(cmap[rec.channel_id], rec.log_time, rec.data, rec.publish_time, rec.sequence)
                    n += 1
                elif isinstance(rec, Metadata):
                    w.add_metadata(rec.name, rec.metadata)
        except (McapError, ValueError, EOFError, OSError, struct.error) as exc:   # a record cut short
            truncated, err = True, f"{type(exc).__name__}: {exc}"
        w.finish()
    os.replace(tmp, dst)
    return RecoveryResult(str(src), str(dst), n, truncated, err)


def _instance_re(instance: str) -> re.Pattern:
    return re.compile(rf"^{re.escape(instance)}-\d{{8}}T\d{{6}}Z-\d+\.mcap$")


def recover_leftovers(directory: str | Path, instance: str) -> list[RecoveryResult]:
    """Recover the instance's ``.part`` files in ``directory`` that no live process holds (flock)."""
    out = []
    pat = _instance_re(instance)
    for part in sorted(Path(directory).glob(f"{instance}-*.mcap.part")):
        if not pat.match(part.name[:-5]):
            continue
        with part.open("rb") as fh:
            if not _lock(fh):
                continue   # a live recorder is writing it
            try:
                res = recover_file(part)
            except RecordingError as exc:
                log.error("leftover %s cannot be recovered: %s (left in place)", part, exc)
                continue
        part.unlink()
        log.warning("recovered leftover %s -> %s: %d messages%s", part, res.target, res.messages,
                    " (truncated)" if res.truncated else "")
        out.append(res)
    return out


class _File:
    """One MCAP file being written: the writer, its channels, the loops configured in it."""

    def __init__(self, path: Path, run_msg: dict, chunk_size: int, now_ns: int) -> None:
        self.part = path.with_name(path.name + ".part")
        self.path = path
        self.fh = self.part.open("wb")
        try:
            _lock(self.fh)
            self.writer = Writer(self.fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
            self.writer.start(library=LIBRARY)
            self.schemas = {kind: self.writer.register_schema(
                schema["title"], SchemaEncoding.JSONSchema, codec.dumps(schema))
                for kind, schema in codec.SCHEMAS.items()}
            self.channels: dict[tuple[str, str], int] = {}
            run = self.writer.register_channel(codec.RUN_TOPIC, MessageEncoding.JSON, self.schemas["run"])
            self.writer.add_message(run, now_ns, codec.dumps(run_msg), now_ns)
            self.writer.flush()
        except BaseException:
            self.fh.close()
            raise
        self.loops: set[str] = set()
        self.windows = 0

    def channel(self, loop_id: str, kind: str) -> int:
        ch = self.channels.get((loop_id, kind))
        if ch is None:
            ch = self.channels[(loop_id, kind)] = self.writer.register_channel(
                codec.loop_topic(loop_id, kind), MessageEncoding.JSON, self.schemas[kind],
                {"loop": loop_id, "kind": kind})
        return ch

    def size(self) -> int:
        return self.fh.tell()

    def finish(self) -> None:
        self.writer.finish()
        self.fh.flush()
        os.fsync(self.fh.fileno())
        self.fh.close()
        os.replace(self.part, self.path)

    def abandon(self) -> None:
        try:
            self.fh.close()
        except OSError:
            pass


class McapRecorder:
    """Records every analysed window (samples, result, alert) and the run configuration to MCAP.

    Parameters
    ----------
    directory : where the files go (created if missing).
    instance : the monitor's name; prefix of the file names (and of what retention may delete).
    run_config : JSON-ready configuration the monitor runs with (``loopwatch.RunConfig``:
        ``instance``, ``alerts`` ``{raise_after, clear_after}``, ``settings``), written first in every file.
    rotate_bytes, rotate_s : roll over at this size (approximate: checked per chunk) or age.
    retention_bytes, retention_s : keep at most this many bytes / this age of finished files (None: no limit).
    flush_s : the chunk in progress is written and flushed at least this often.
    queue_max : windows waiting for the writer thread; beyond, windows are dropped and counted.
    retry_s : after a write error, time before the next attempt to open a new file.
    chunk_size : uncompressed bytes per MCAP chunk.
    clock, wall : monotonic and Unix clocks (injected for tests).
    recover : recover the instance's leftover ``.part`` files on start (in the writer thread,
        before the first window is written).
    """

    name = "recording"

    def __init__(self, directory: str | Path, *, instance: str = "main", run_config: dict | None = None,
                 rotate_bytes: int = 256 << 20, rotate_s: float = 3600.0, retention_bytes: int | None = None,
                 retention_s: float | None = None, flush_s: float = 2.0, queue_max: int = 1000,
                 retry_s: float = 30.0, chunk_size: int = 1 << 20, clock: Callable[[], float] = time.monotonic,
                 wall: Callable[[], float] = time.time, recover: bool = True) -> None:
        self.dir = Path(directory)
        self.instance = instance
        self.run_config = dict(run_config or {})
        self.run_config.setdefault("instance", instance)
        self.run_config.setdefault("run_id", uuid.uuid4().hex)   # one monitor run (alert states start afresh)
        self.rotate_bytes, self.rotate_s = int(rotate_bytes), float(rotate_s)
        self.retention_bytes, self.retention_s = retention_bytes, retention_s
        self.flush_s, self.retry_s, self.chunk_size = float(flush_s), float(retry_s), int(chunk_size)
        self.clock, self.wall = clock, wall
        self._q: queue.Queue = queue.Queue(maxsize=queue_max)
        self._file: _File | None = None
        self._opened_at = self._flushed_at = 0.0
        self._dirty = False
        self._serial = 0
        self.state = "ok"
        self.last_error: str | None = None
        self._retry_at = 0.0
        self.dropped: Counter[str] = Counter()
        self.windows_recorded = 0
        self.windows_flushed = 0
        self.alerts_recorded = 0
        self.cpu_s = 0.0   # CPU time of the writer thread (encoding, compression, writing)
        self.files_finished = 0
        self.last_file: str | None = None
        self.files_deleted = 0
        self.recovered: list[RecoveryResult] = []
        self._lock = threading.Lock()
        self._recover = recover
        self._thread = threading.Thread(target=self._run, name="loopwatch-recorder", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ sink side (monitor thread)
    def on_window(self, loop_id: str, window: Any, result: Any, alert: Any = None) -> None:
        """Queue a window for writing; never blocks: a full queue drops it (counted)."""
        try:
            self._q.put_nowait((window, result, alert))
        except queue.Full:
            with self._lock:
                self.dropped["queue_full"] += 1
            if self.dropped["queue_full"] in (1, 10, 100) or self.dropped["queue_full"] % 1000 == 0:
                log.error("recording queue full (%d windows): %d window(s) not recorded so far",
                          self._q.maxsize, self.dropped["queue_full"])

    def status(self) -> dict[str, Any]:
        with self._lock:
            return {
                "state": self.state, "dir": str(self.dir),
                "file": str(self._file.part) if self._file else None,
                "windows_recorded": self.windows_recorded, "windows_flushed": self.windows_flushed,
                "alerts_recorded": self.alerts_recorded, "windows_dropped": dict(self.dropped),
                "writer_cpu_s": round(self.cpu_s, 3),
                "queued": self._q.qsize(), "files_finished": self.files_finished, "last_file": self.last_file,
                "files_deleted_by_retention": self.files_deleted,
                "recovered_on_start": [r.target for r in self.recovered], "last_error": self.last_error,
            }

    def close(self, timeout: float | None = 60.0) -> None:
        """Write what is queued, finish the file (renamed to ``.mcap``), stop the writer thread."""
        if self._thread.is_alive():
            self._q.put(_STOP)
            self._thread.join(timeout)

    # ------------------------------------------------------------------ writer thread
    def _run(self) -> None:
        if self._recover:   # in the writer thread: a large leftover must not delay the monitor's start
            try:
                self.dir.mkdir(parents=True, exist_ok=True)
                found = recover_leftovers(self.dir, self.instance)
                with self._lock:
                    self.recovered += found
            except OSError as exc:
                self._degrade(exc)
        while True:
            try:
                item = self._q.get(timeout=self._wait())
            except queue.Empty:
                item = None
            if item is _STOP:
                break
            cpu0 = time.thread_time()
            try:
                if item is not None:
                    self._write(*item)
                self._housekeeping()
            except OSError as exc:
                self._degrade(exc)
            except Exception as exc:  # noqa: BLE001 - a bad window must not end the recorder
                with self._lock:
                    self.dropped["encode_error"] += 1
                log.error("recording a window failed: %r", exc)
            self.cpu_s += time.thread_time() - cpu0
        try:
            self._rotate()
        except OSError as exc:
            self._degrade(exc)
        with self._lock:
            if self.state != "degraded":
                self.state = "closed"

    def _wait(self) -> float:
        now = self.clock()
        if self._file is None:
            return max(0.05, self._retry_at - now) if self.state == "degraded" else 3600.0
        due = self._opened_at + self.rotate_s
        if self._dirty:
            due = min(due, self._flushed_at + self.flush_s)
        return max(0.01, due - now)

    def _write(self, window: Any, result: Any, alert: Any) -> None:
        if self._file is None and not self._open():
            with self._lock:
                self.dropped["degraded"] += 1
            return
        f = self._file
        t_ns = codec.seconds_to_ns(window.t)
        end = int(t_ns[-1])
        loop = window.loop_id
        w = f.writer
        if loop not in f.loops:
            f.loops.add(loop)
            w.add_message(f.channel(loop, "config"), end, codec.dumps(codec.encode_loop_config(loop, window, end)),
                          end)
        seq = int(window.seq)
        w.add_message(f.channel(loop, "window"), end, codec.encode_window(window, t_ns), end, seq)
        w.add_message(f.channel(loop, "result"), end, codec.dumps(codec.encode_result(loop, seq, end, result)),
                      end, seq)
        if alert is not None:
            w.add_message(f.channel(loop, "alert"), end, codec.dumps(codec.encode_alert(alert, end, self.instance)),
                          end, seq)
        f.windows += 1
        self._dirty = True
        with self._lock:
            self.windows_recorded += 1
            self.alerts_recorded += alert is not None

    def _housekeeping(self) -> None:
        if self._file is None:
            return
        now = self.clock()
        if now - self._opened_at >= self.rotate_s or self._file.size() >= self.rotate_bytes:
            self._rotate()   # the next window opens the next file
        elif self._dirty and now - self._flushed_at >= self.flush_s:
            self._flush()

    def _flush(self) -> None:
        self._file.writer.flush()
        self._flushed_at = self.clock()
        self._dirty = False
        with self._lock:
            self.windows_flushed = self.windows_recorded

    def _open(self) -> bool:
        now = self.clock()
        if self.state == "degraded":
            if now < self._retry_at:
                return False
            try:   # what the failed file left behind, now that it is closed
                self.recovered += recover_leftovers(self.dir, self.instance)
            except OSError:
                pass
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(self.wall()))
            self._serial += 1
            path = self.dir / f"{self.instance}-{stamp}-{self._serial:04d}.mcap"
            run_msg = codec.encode_run_config(self.run_config, int(self.wall() * 1e9))
            self._file = _File(path, run_msg, self.chunk_size, int(self.wall() * 1e9))
        except OSError as exc:
            self._degrade(exc)
            return False
        self._opened_at = self._flushed_at = self.clock()
        self._dirty = False
        if self.state == "degraded":
            log.warning("recording resumed in %s after: %s", self.dir, self.last_error)
        with self._lock:
            self.state = "ok"
        return True

    def _rotate(self) -> None:
        f, self._file = self._file, None
        if f is None:
            return
        try:
            f.finish()
        except OSError:
            f.abandon()
            raise
        with self._lock:
            self.windows_flushed = self.windows_recorded
            self.files_finished += 1
            self.last_file = str(f.path)
        self._dirty = False
        self._retain()

    def _retain(self) -> None:
        if self.retention_bytes is None and self.retention_s is None:
            return
        pat = _instance_re(self.instance)
        files = []
        for p in self.dir.iterdir():
            if pat.match(p.name):
                try:
                    st = p.stat()
                except OSError:
                    continue
                files.append((st.st_mtime, p.name, p, st.st_size))
        files.sort()
        total = sum(f[3] for f in files)
        now = self.wall()
        for i, (mtime, _, p, size) in enumerate(files):
            if i == len(files) - 1:
                break   # the newest finished file is always kept
            too_big = self.retention_bytes is not None and total > self.retention_bytes
            too_old = self.retention_s is not None and now - mtime > self.retention_s
            if not (too_big or too_old):
                continue
            try:
                p.unlink()
            except OSError as exc:
                log.error("retention: cannot delete %s: %s", p, exc)
                continue
            total -= size
            with self._lock:
                self.files_deleted += 1
            log.info("retention: deleted %s (%d bytes)", p, size)

    def _degrade(self, exc: OSError) -> None:
        if self._file is not None:
            self._file.abandon()
            self._file = None
        first = self.state != "degraded"
        with self._lock:
            self.state = "degraded"
            self.last_error = f"{type(exc).__name__}: {exc}"
        self._retry_at = self.clock() + self.retry_s
        if first:
            log.error("recording degraded (monitoring continues; windows are not recorded; retry every %g s): %s",
                      self.retry_s, self.last_error)
