import os
from pathlib import Path

import pytest

#: the project's real plant data lives beside the repository (never copied into it)
SHARED_DATA = Path(os.environ.get("LOOPWATCH_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))

#: fixed loopback ports of the tests are ``PORT_BASE + n``; set LOOPWATCH_TEST_PORT_BASE to run two
#: checkouts' suites side by side without clashing
PORT_BASE = int(os.environ.get("LOOPWATCH_TEST_PORT_BASE", "17500"))


def loopback_port(n: int) -> int:
    """The fixed 127.0.0.1 port number ``n`` of the test suite (0 <= n < 100)."""
    if not 0 <= n < 100:
        raise ValueError(f"test port offset {n} must be in [0, 100)")
    return PORT_BASE + n


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (set LOOPWATCH_SHARED_DATA)")
    return SHARED_DATA
