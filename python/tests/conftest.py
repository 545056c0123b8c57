"""Shared fixtures: the vector file, read once; and hypothesis without its deadline.

The tests assert behaviour, not speed: a loaded CI runner once took 905 ms over an example that
takes 0.1 ms, and hypothesis's default 200 ms deadline failed the test. Speed is the benches'
(bench/)."""

import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings

settings.register_profile("asserv", deadline=None)
settings.load_profile("asserv")

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def vectors() -> dict[str, Any]:
    with (ROOT / "protocol" / "vectors.toml").open("rb") as f:
        return tomllib.load(f)
