"""What the tests share: the repository's maps and the harness binary to compare against.

`tests/tests/e2e/python.rs` runs these tests with `VPM_HARNESS` set to the harness it built; run by
hand, set it to `target/release/harness` (the tests that need it fail without it).
"""

import os
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
MAPS = REPOSITORY / "scenarios" / "maps"


@pytest.fixture(scope="session")
def harness() -> Path:
    path = os.environ.get("VPM_HARNESS")
    assert path, "VPM_HARNESS must name the harness binary (target/release/harness)"
    assert Path(path).is_file(), f"VPM_HARNESS={path} is not a file"
    return Path(path)
