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
    # and the BLAS kernel OpenBLAS picked for the CPU (OPENBLAS_CORETYPE overrides it; numpy and scipy
    # each load one): on an AMD EPYC of family 26 it picks Haswell, and there 159 #4 at 60 s takes
    # another path than with SkylakeX, which gives the path of every earlier machine (BENCHMARKS.md,
    # issue 8, session 54)
    import numpy  # noqa: F401  (loads OpenBLAS, which threadpoolctl lists only once loaded)
    from threadpoolctl import threadpool_info

    blas = ", ".join(dict.fromkeys(f"{i.get('internal_api')} {i.get('architecture')}" for i in threadpool_info()
                                   if i.get("user_api") == "blas")) or "BLAS -"
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {stack}, {blas}"
