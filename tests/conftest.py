import os
from pathlib import Path

import pytest

#: the project's real plant data lives beside the repository (never copied into it)
SHARED_DATA = Path(os.environ.get("LOOPWATCH_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (set LOOPWATCH_SHARED_DATA)")
    return SHARED_DATA
