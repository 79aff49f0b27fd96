"""Benchmarks: run by ``make bench`` (``pytest -m bench -s tests/bench``), never by default."""

import os
import platform


def machine_note() -> str:
    """One line naming the machine the figures come from."""
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    # the numerical stack too: a fit's last bits (and, at a knife edge, a verdict) depend on its versions
    from importlib.metadata import PackageNotFoundError, version

    def ver(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "-"

    stack = ", ".join(f"{n} {ver(n)}" for n in ("numpy", "scipy", "numba"))
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {stack}"
