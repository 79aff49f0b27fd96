"""Settings of the always-on monitor: one TOML file, environment overrides, validated at load.

Priority: keyword arguments > environment (``LOOPWATCH_``, nested with ``__``, e.g.
``LOOPWATCH_ALERTS__RAISE_AFTER=5``, lists as JSON) > the TOML file > defaults.  Every key is
checked (``extra="forbid"``): a misspelled key is an error that names it.  Errors are raised as
:class:`SettingsError` with one line per problem, ``key.path: message (got value)``.

Example: ``deploy/monitor.toml``.
"""

from __future__ import annotations

import contextvars
import math
import re
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict, TomlConfigSettingsSource

from .errors import ServiceError

__all__ = [
    "SettingsError",
    "ZenohSettings",
    "KeySettings",
    "WindowSettings",
    "AlertSettings",
    "AnalysisSettings",
    "IngestSettings",
    "LoopSettings",
    "RecordingSettings",
    "RerunSettings",
    "MonitorSettings",
    "load_settings",
]

_ENDPOINT = re.compile(r"^(tcp|udp|tls|quic|unixsock-stream)/\S+$")
_KEY_SEGMENT = re.compile(r"^[A-Za-z0-9_.\-]+(/[A-Za-z0-9_.\-]+)*$")
_CONFIG_PATH: contextvars.ContextVar[Path | None] = contextvars.ContextVar("loopwatch_config_path", default=None)


class SettingsError(ServiceError):
    """The configuration is invalid; the message lists every bad key with the value given."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ZenohSettings(_Strict):
    """The zenoh session.

    ``mode = "peer"`` with a ``listen`` endpoint on 127.0.0.1 is the embedded default (no router
    needed: publishers connect to it).  ``mode = "client"`` with ``connect`` joins a router
    (``deploy/zenoh-router.json5``).  Multicast scouting is always off.
    """

    mode: Literal["peer", "client"] = "peer"
    listen: list[str] = ["tcp/127.0.0.1:7447"]
    connect: list[str] = []
    gossip: bool = False

    @field_validator("listen", "connect")
    @classmethod
    def _endpoints(cls, v: list[str]) -> list[str]:
        bad = [e for e in v if not _ENDPOINT.match(e)]
        if bad:
            raise ValueError(f"endpoint(s) {bad} must look like 'tcp/127.0.0.1:7447'")
        return v

    @model_validator(mode="after")
    def _reachable(self) -> "ZenohSettings":
        if self.mode == "client" and not self.connect:
            raise ValueError("mode 'client' needs at least one connect endpoint (the router), or it reaches nobody")
        return self


class KeySettings(_Strict):
    """Key expressions: samples under ``{prefix}/**``, alerts on ``{alert_prefix}/{loop_id}``."""

    prefix: str = "plant"
    alert_prefix: str = "loopwatch/alerts"

    @field_validator("prefix", "alert_prefix")
    @classmethod
    def _key(cls, v: str) -> str:
        if not _KEY_SEGMENT.match(v):
            raise ValueError("must be '/'-separated segments of letters, digits, '_', '-', '.', no wildcards")
        return v


class WindowSettings(_Strict):
    """Sliding window: ``length``/``hop`` in samples, or ``length_s``/``hop_s`` in seconds.

    Seconds are converted with the loop's sample time (configured or inferred).
    ``lateness`` (samples) is how far the newest sample of a loop may run ahead of a window's
    end before the window is closed even though another signal of the loop has not reached it.
    """

    length: Annotated[int, Field(ge=64)] | None = None
    hop: Annotated[int, Field(ge=1)] | None = None
    length_s: Annotated[float, Field(gt=0)] | None = None
    hop_s: Annotated[float, Field(gt=0)] | None = None
    lateness: Annotated[int, Field(ge=0)] = 64

    @model_validator(mode="after")
    def _one_unit(self) -> "WindowSettings":
        if self.length is not None and self.length_s is not None:
            raise ValueError("give the window length in samples (length) or in seconds (length_s), not both")
        if self.hop is not None and self.hop_s is not None:
            raise ValueError("give the hop in samples (hop) or in seconds (hop_s), not both")
        return self


class AlertSettings(_Strict):
    """Raise after ``raise_after`` consecutive non-linear windows, clear after ``clear_after`` clean ones."""

    raise_after: Annotated[int, Field(ge=1)] = 3
    clear_after: Annotated[int, Field(ge=1)] = 3


class AnalysisSettings(_Strict):
    """What is analysed and by how many worker processes.

    ``signal``: ``pv``, ``op`` or ``error`` (``sp - pv``).  ``method``: ``robust`` (default) or
    ``paper``; ``threshold``: the figure a window must exceed to read non-linear (the robust
    method's least mean-wave DNL, or the paper's TDNL); unset, each method's own default.  ``workers = 0`` analyses in a thread
    of the monitor process (tests, tiny plants); ``>= 1`` uses that many worker processes.
    """

    signal: Literal["pv", "op", "error"] = "pv"
    method: Literal["robust", "paper"] = "robust"
    threshold: Annotated[float, Field(gt=0)] | None = None
    workers: Annotated[int, Field(ge=0, le=64)] = 1


class IngestSettings(_Strict):
    """Edge checks: accepted time range (Unix s), log-rate limit for rejections, most loops tracked."""

    time_min: float = 946684800.0    # 2000-01-01
    time_max: float = 4102444800.0   # 2100-01-01
    max_logs_per_s: Annotated[float, Field(gt=0)] = 1.0
    max_loops: Annotated[int, Field(ge=1)] = 100_000

    @model_validator(mode="after")
    def _range(self) -> "IngestSettings":
        if not (math.isfinite(self.time_min) and math.isfinite(self.time_max) and self.time_min < self.time_max):
            raise ValueError(f"time_min ({self.time_min}) must be < time_max ({self.time_max}), both finite")
        return self


class RecordingSettings(_Strict):
    """MCAP recording of every analysed window (``loopwatch replay`` reads it back).

    Files go to ``dir`` as ``{instance}-{UTC start}-{n}.mcap`` (``.part`` while written); they
    roll over at ``rotate_bytes`` or ``rotate_s``; the oldest are deleted beyond
    ``retention_bytes`` / ``retention_s`` (unset: kept forever).  ``flush_s`` bounds what a crash
    can lose.  ``queue_windows`` windows may wait for the writer; beyond, windows are dropped
    (counted in the status) rather than slowing the monitor down.
    """

    enabled: bool = False
    dir: Path = Path("recordings")
    rotate_bytes: Annotated[int, Field(ge=1 << 20)] = 256 << 20
    rotate_s: Annotated[float, Field(gt=0)] = 3600.0
    retention_bytes: Annotated[int, Field(gt=0)] | None = None
    retention_s: Annotated[float, Field(gt=0)] | None = None
    flush_s: Annotated[float, Field(gt=0, le=60)] = 2.0
    queue_windows: Annotated[int, Field(ge=1)] = 1000

    @model_validator(mode="after")
    def _limits(self) -> "RecordingSettings":
        if self.flush_s > self.rotate_s:
            raise ValueError(f"flush_s ({self.flush_s}) must be <= rotate_s ({self.rotate_s})")
        if self.retention_bytes is not None and self.retention_bytes < self.rotate_bytes:
            raise ValueError(f"retention_bytes ({self.retention_bytes}) must be >= rotate_bytes "
                             f"({self.rotate_bytes}), or every finished file would be deleted at once")
        if self.retention_s is not None and self.retention_s < self.rotate_s:
            raise ValueError(f"retention_s ({self.retention_s}) must be >= rotate_s ({self.rotate_s}), "
                             "or files would be deleted as soon as they are finished")
        return self


class LoopSettings(_Strict):
    """Per-loop overrides (``[loops."area1/FIC101"]``); unset fields use the global ones."""

    sample_time_s: Annotated[float, Field(gt=0)] | None = None
    signal: Literal["pv", "op", "error"] | None = None
    window: WindowSettings | None = None


# --- rerun dashboard (issue 6) ---------------------------------------------------------------
class RerunSettings(_Strict):
    """The rerun dashboard (``adapters.rerun_dashboard``); off unless ``spec`` is set.

    ``spec``: ``save:PATH.rrd``, ``serve`` / ``serve:PORT`` / ``serve:HOST:PORT`` (gRPC on ``PORT``,
    default 9876, and the web viewer on ``web_port``, bound to ``host``), or ``connect:ADDR``.
    Throttling limits what is drawn, never what is analysed: ``draw_per_s`` windows' signals and
    ``explain_per_s`` windows' IMFs per wall second; ``focus`` loops are always drawn.
    """

    spec: str | None = None
    host: str = "127.0.0.1"
    web_port: Annotated[int, Field(ge=0, le=65535)] = 9090
    draw_per_s: Annotated[float, Field(ge=0)] = 50.0
    explain_per_s: Annotated[float, Field(ge=0)] = 2.0
    overview_every_s: Annotated[float, Field(gt=0)] = 2.0
    overview_rows: Annotated[int, Field(ge=1)] = 50
    focus: list[str] = []

    @field_validator("spec")
    @classmethod
    def _spec(cls, v: str | None) -> str | None:
        if v is not None:
            from adapters.rerun_dashboard import parse_rerun_spec

            parse_rerun_spec(v)  # RerunSpecError is a ValueError: reported with the key
        return v
# --- end rerun dashboard ----------------------------------------------------------------------


class MonitorSettings(BaseSettings):
    """Everything ``loopwatch monitor`` needs; see ``deploy/monitor.toml``."""

    model_config = SettingsConfigDict(env_prefix="LOOPWATCH_", env_nested_delimiter="__", extra="forbid",
                                      frozen=True)

    instance: str = "main"
    sample_time_s: Annotated[float, Field(gt=0)] | None = None
    zenoh: ZenohSettings = ZenohSettings()
    keys: KeySettings = KeySettings()
    window: WindowSettings = WindowSettings()
    alerts: AlertSettings = AlertSettings()
    analysis: AnalysisSettings = AnalysisSettings()
    ingest: IngestSettings = IngestSettings()
    recording: RecordingSettings = RecordingSettings()
    loops: dict[str, LoopSettings] = {}
    rerun: RerunSettings = RerunSettings()  # issue 6: off by default

    @field_validator("instance")
    @classmethod
    def _instance(cls, v: str) -> str:
        if not re.match(r"^[A-Za-z0-9_.\-]+$", v):
            raise ValueError("must be one key segment of letters, digits, '_', '-', '.'")
        return v

    @field_validator("loops")
    @classmethod
    def _loop_ids(cls, v: dict[str, LoopSettings]) -> dict[str, LoopSettings]:
        bad = [k for k in v if not _KEY_SEGMENT.match(k)]
        if bad:
            raise ValueError(f"loop id(s) {bad} must be '/'-separated segments without wildcards")
        return v

    @classmethod
    def settings_customise_sources(cls, settings_cls, init_settings, env_settings, dotenv_settings,
                                   file_secret_settings):
        path = _CONFIG_PATH.get()
        files = (TomlConfigSettingsSource(settings_cls, toml_file=path),) if path is not None else ()
        return (init_settings, env_settings, *files)


def _format(exc: ValidationError, source: str) -> str:
    lines = []
    for e in exc.errors(include_url=False):
        loc = ".".join(str(p) for p in e["loc"]) or "(top level)"
        got = e.get("input")
        shown = repr(got) if not isinstance(got, dict) else "{...}"
        lines.append(f"  - {loc}: {e['msg']} (got {shown[:80]})")
    return f"{len(lines)} config error(s) in {source}:\n" + "\n".join(lines)


def load_settings(path: str | Path | None = None, **overrides) -> MonitorSettings:
    """Load and validate the settings from ``path`` (TOML), the environment and ``overrides``.

    Raises
    ------
    SettingsError
        the file is missing or not TOML, or any key is invalid (all problems listed).
    """
    p = Path(path) if path is not None else None
    if p is not None:
        if not p.is_file():
            raise SettingsError(f"config file {p} not found")
        import tomllib

        try:
            tomllib.loads(p.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SettingsError(f"config file {p} is not valid TOML: {exc}") from None
    token = _CONFIG_PATH.set(p)
    try:
        return MonitorSettings(**overrides)
    except ValidationError as exc:
        raise SettingsError(_format(exc, str(p) if p else "settings")) from None
    finally:
        _CONFIG_PATH.reset(token)
