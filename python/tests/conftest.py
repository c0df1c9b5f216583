"""Shared fixtures: the bundled data and the `blockwalk` command, when it is built."""

import os
import pathlib
import shutil

import geopandas as gpd
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = ROOT / "data"


def data(rel: str) -> pathlib.Path:
    p = DATA / rel
    assert p.exists(), f"missing test data {p}"
    return p


def cli_binary():
    """The `blockwalk` command: $BLOCKWALK_BIN, else the workspace's release or debug build (in
    $CARGO_TARGET_DIR or target/), else one on PATH; None when there is none."""
    env = os.environ.get("BLOCKWALK_BIN")
    if env:
        return env
    targets = [os.environ.get("CARGO_TARGET_DIR"), str(ROOT / "target")]
    for t in filter(None, targets):
        for profile in ("release", "debug"):
            p = pathlib.Path(t) / profile / "blockwalk"
            if p.is_file() and os.access(p, os.X_OK):
                return str(p)
    return shutil.which("blockwalk")


@pytest.fixture(scope="session")
def bubenec():
    return gpd.read_file(data("bubenec/buildings.shp")), gpd.read_file(data("bubenec/streets.shp"))


@pytest.fixture(scope="session")
def helsinki():
    return (
        gpd.read_file(data("helsinki/buildings.shp")),
        gpd.read_file(data("helsinki/streets_blockclass.shp")),
    )
