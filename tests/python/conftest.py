"""Fixtures of the Python bindings' tests: a small simulated capture and its field, made once per
run by the command line (the reference the bindings are compared with)."""

import json
import os
import pathlib
import subprocess

import pytest

import lightstage as ls

ROOT = pathlib.Path(__file__).resolve().parents[2]
ENVMAP = ROOT / "data" / "envmaps" / "sky_sun.exr"
# A small camera keeps each job to a second or so; the built-in dome's 151 LEDs are kept.
RESOLUTION = 40


def cli_path():
    path = os.environ.get("LIGHTSTAGE_CLI", str(ROOT / "build" / "app" / "cli" / "lightstage"))
    if not os.access(path, os.X_OK):
        pytest.skip(f"the lightstage executable is not built ({path})")
    return path


def run_cli(*args, check=True):
    """Runs `lightstage ARGS...`; returns the CompletedProcess (text output)."""
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True,
                          check=check, timeout=600)


@pytest.fixture(scope="session")
def cli():
    return run_cli


@pytest.fixture(scope="session")
def stage_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("stage") / "stage.json"
    run_cli("stage", "--write", path)
    stage = json.loads(path.read_text())
    stage["camera"]["width"] = stage["camera"]["height"] = RESOLUTION
    path.write_text(json.dumps(stage))
    return path


@pytest.fixture(scope="session")
def session_dir(tmp_path_factory, stage_file):
    path = tmp_path_factory.mktemp("capture") / "session"
    run_cli("capture", "--stage", stage_file, "--out", path, "--quiet")
    return path


@pytest.fixture(scope="session")
def field_file(tmp_path_factory, session_dir):
    path = tmp_path_factory.mktemp("field") / "field.exr"
    run_cli("build", session_dir, "--out", path, "--quiet")
    return path


@pytest.fixture
def field(field_file):
    return ls.Field.open(field_file)
