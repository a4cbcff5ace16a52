"""`pip install --no-build-isolation .` into a fresh `python3 -m venv --system-site-packages`, offline (no index: every
dependency is Debian's), installs a package that imports outside the source and build trees and reports the CMake
project's version. The native module is the one this build tree made (FEEDID_CMAKE_BUILD_DIR): a from-scratch CMake
build inside pip takes minutes on two cores; setup.py's configure step is the only part this does not run."""

import os
import pathlib
import re
import shutil
import subprocess
import sys

from conftest import BUILD_DIR, SOURCE_DIR


def project_version():
    return re.search(r"project\(feedid VERSION ([0-9.]+)", (SOURCE_DIR / "CMakeLists.txt").read_text()).group(1)


def test_pip_install_into_a_fresh_venv_offline(folder):
    # the repository's files pip reads (a copy, so that setuptools' build folders stay out of the source tree)
    source = folder / "source"
    for name in ("setup.py", "pyproject.toml", "CMakeLists.txt", "README.md"):
        source.mkdir(exist_ok=True)
        shutil.copy(SOURCE_DIR / name, source / name)
    shutil.copytree(SOURCE_DIR / "python", source / "python", ignore=shutil.ignore_patterns("__pycache__"))
    venv = folder / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--clear", str(venv)], check=True)
    python = venv / "bin" / "python"
    # nothing from outside: no PYTHONPATH (the build tree), no pip configuration of this machine (extra indexes, links)
    environment = {key: value for key, value in os.environ.items()
                   if key != "PYTHONPATH" and not key.startswith("PIP_")}
    environment.update(FEEDID_CMAKE_BUILD_DIR=str(BUILD_DIR), CMAKE_BUILD_PARALLEL_LEVEL="1")
    installed = subprocess.run([str(python), "-m", "pip", "--isolated", "install", "--no-build-isolation", "--no-index",
                                "--no-cache-dir", "."],
                               cwd=source, env=environment, capture_output=True, text=True)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    check = ("import feedid, pathlib; print(feedid.__version__); print(pathlib.Path(feedid.__file__).parent); "
             "import feedid.fleet; print(feedid.identify(feedid.synth(seed=1, slow_passes=False), "
             "force_constant='force_constant_N_per_A').status)")
    imported = subprocess.run([str(python), "-c", check], cwd=folder, env=environment, capture_output=True,
                              text=True)
    assert imported.returncode == 0, imported.stderr
    version, location, status = imported.stdout.split()
    assert version == project_version()
    package = pathlib.Path(location)
    assert package.is_relative_to(venv) and package.name == "feedid"
    assert (package / "py.typed").exists() and (package / "__init__.pyi").exists()
    assert status == "partial"
