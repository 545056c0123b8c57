"""Shared fixtures: the vector file, read once; and hypothesis's profile.

No deadline: the tests assert behaviour, not speed (a loaded CI runner once took 905 ms over an
example that takes 0.1 ms; speed is the benches', bench/). Derandomized, without an example
database: every run draws the same examples, so that a failure is reproduced by running the
test again; the soaks in bench/ draw new robots and masters on every seed."""

import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings

settings.register_profile("asserv", deadline=None, derandomize=True, database=None)
settings.load_profile("asserv")

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def vectors() -> dict[str, Any]:
    with (ROOT / "protocol" / "vectors.toml").open("rb") as f:
        return tomllib.load(f)
