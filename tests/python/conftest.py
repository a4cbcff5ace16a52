"""Shared pieces of the Python tests: where the CLI, the reference data and the test files are (ctest sets them, see
python/CMakeLists.txt), the CLI run the module is compared with, and numeric comparison of documents."""

import json
import math
import os
import pathlib
import shutil
import subprocess

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("FEEDID_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2])).resolve()
BUILD_DIR = pathlib.Path(os.environ.get("FEEDID_BUILD_DIR", SOURCE_DIR / "build")).resolve()
CLI = str(pathlib.Path(os.environ.get("FEEDID_CLI", BUILD_DIR / "feedid")).resolve())
SHARED_DATA = pathlib.Path(os.environ.get("FEEDID_SHARED_DATA", SOURCE_DIR.parent / "shared" / "data")).resolve()
TEST_TMP = pathlib.Path(os.environ.get("FEEDID_TEST_TMP", BUILD_DIR / "test-files" / "python")).resolve()

EMPS = SHARED_DATA / "emps" / "DATA_EMPS.mat"
SINUMERIK = SHARED_DATA / "sinumerik-trace" / "X_BK300_1.xml"
EMPS_CHANNELS = {"position": "qm", "current": "vir"}


def shared(path: pathlib.Path) -> str:
    if not path.exists():
        pytest.skip(f"{path} not found (the reference recordings are read from ../shared/data)")
    return str(path)


@pytest.fixture
def emps() -> str:
    return shared(EMPS)


@pytest.fixture
def sinumerik() -> str:
    return shared(SINUMERIK)


@pytest.fixture
def folder(request) -> pathlib.Path:
    """A folder of this test's own inside the build tree (ctest runs test files in parallel processes)."""
    path = TEST_TMP / request.node.module.__name__ / request.node.name
    shutil.rmtree(path, ignore_errors=True)
    path.mkdir(parents=True)
    return path


def run_cli(*arguments: str, expect=0) -> subprocess.CompletedProcess:
    """Runs the feedid command line; checks its exit code (unless expect is None)."""
    completed = subprocess.run([CLI, *map(str, arguments)], capture_output=True, text=True)
    assert expect is None or completed.returncode == expect, \
        f"feedid {' '.join(map(str, arguments))}: exit {completed.returncode}\n{completed.stderr}"
    return completed


def cli_json(*arguments: str) -> dict:
    """A command's --json - document."""
    return json.loads(run_cli(*arguments, "--json", "-").stdout)


def cli_error(*arguments: str, expect: int) -> str:
    """The last line the command prints on stderr (its error), without `feedid: `."""
    lines = run_cli(*arguments, expect=expect).stderr.strip().splitlines()
    assert lines and lines[-1].startswith("feedid: "), lines
    return lines[-1][len("feedid: "):]


def assert_documents_equal(actual, expected, relative: float, where: str = "document") -> None:
    """Equal structure, strings and booleans; numbers within `relative` (nulls where nulls)."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict), where
        assert sorted(actual) == sorted(expected), f"{where}: keys {sorted(actual)} != {sorted(expected)}"
        for key in expected:
            assert_documents_equal(actual[key], expected[key], relative, f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(actual) == len(expected), f"{where}: lengths differ"
        for index, (a, e) in enumerate(zip(actual, expected)):
            assert_documents_equal(a, e, relative, f"{where}[{index}]")
    elif isinstance(expected, bool) or expected is None or isinstance(expected, str):
        assert actual == expected, f"{where}: {actual!r} != {expected!r}"
    else:
        assert isinstance(actual, (int, float)) and not isinstance(actual, bool), f"{where}: {actual!r}"
        assert math.isclose(actual, expected, rel_tol=relative, abs_tol=0.0) or actual == expected, \
            f"{where}: {actual!r} != {expected!r} (relative {relative})"


@pytest.fixture(scope="module")
def postgres(request):
    """A PostgreSQL server of this test module's own (postgres_server.py); the test is skipped where none can run."""
    from postgres_server import PostgresServer
    server = PostgresServer(TEST_TMP / f"{request.module.__name__}-postgres-{os.getpid()}")
    why_not = server.start()
    if why_not:
        server.stop()
        pytest.skip(why_not)
    yield server
    server.stop()
