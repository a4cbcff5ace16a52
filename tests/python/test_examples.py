"""The Python examples (examples/python) run as a user runs them, and print what they promise."""

import os
import re
import subprocess
import sys

from conftest import SOURCE_DIR

EXAMPLES = SOURCE_DIR / "examples" / "python"


def run(name, *arguments):
    completed = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, arguments)], capture_output=True,
                               text=True, env=dict(os.environ))
    assert completed.returncode == 0, completed.stderr
    return completed.stdout


def test_identify_emps(emps):
    output = run("identify_emps.py", emps)
    mass = re.search(r"^mass_kg\s+M\s+kg\s+(\S+)\s+(\S+)\s+(\S+)\s+95\.1089\s+0\.1085\s+(\S+)$", output,
                     re.MULTILINE)
    assert mass, output
    assert abs(float(mass.group(4))) < 2.0  # within 2 % of the published mass (tests/identify/test_identify.cpp)


def test_streaming_rls():
    output = run("streaming_rls.py", "120")
    rows = re.findall(r"^\s+(\d+\.\d)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)$", output, re.MULTILINE)
    last = rows[-1]
    assert float(last[0]) == 120.0 and abs(float(last[1]) - 89.1) < 1.0  # followed the load within a kilogram
    assert abs(float(last[3]) - 742.8) < 1.0
    assert "120000 updates" in output


def test_fleet(folder):
    output = run("fleet.py", "--traces", "6", "--workers", "2", "--folder", folder)
    assert "6 traces in" in output and "'partial': 6" in output
    assert len(list(folder.glob("axis*.csv"))) == 6
