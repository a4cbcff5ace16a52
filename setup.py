"""Installs feedid's Python module: `pip install --no-build-isolation .` (offline; setuptools and wheel from Debian).

The native module (python/src, pybind11) is built by the project's CMake, which also builds the C++ library it links:
a Release build of only what the module needs, in build-pip/cmake. To package a module that an existing CMake build
tree has built already (a development checkout, the tests), name that tree:
    FEEDID_CMAKE_BUILD_DIR=build pip install --no-build-isolation .
Either way the version is the CMake project's.
"""

import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).parent.resolve()
VERSION = re.search(r"project\(feedid VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)
BUILD_BASE = "build-pip"


class CMakeBuild(build_ext):
    """Builds the extension with CMake (target feedid_python) and copies it where setuptools packages it."""

    def build_extension(self, extension: Extension) -> None:
        existing = os.environ.get("FEEDID_CMAKE_BUILD_DIR")
        build_dir = pathlib.Path(existing).resolve() if existing else ROOT / BUILD_BASE / "cmake"
        if not existing:
            self.configure(build_dir)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 2))
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "feedid_python", "-j", jobs], check=True)
        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        built = build_dir / "python" / "feedid" / f"_feedid{suffix}"
        if not built.exists():
            raise RuntimeError(f"{built} was not built: is {build_dir} configured for this Python ({sys.version})?")
        target = pathlib.Path(self.get_ext_fullpath(extension.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, target)

    def configure(self, build_dir: pathlib.Path) -> None:
        arguments = ["cmake", "-S", str(ROOT), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
                     f"-DPython_EXECUTABLE={sys.executable}", "-DFEEDID_BUILD_TESTS=OFF", "-DFEEDID_BUILD_BENCH=OFF",
                     "-DFEEDID_BUILD_EXAMPLES=OFF"]
        if shutil.which("ccache"):
            arguments.append("-DCMAKE_CXX_COMPILER_LAUNCHER=ccache")
        subprocess.run(arguments, check=True)


(ROOT / BUILD_BASE).mkdir(exist_ok=True)
setup(
    name="feedid",
    version=VERSION,
    description="Rapid parameter estimation and health monitoring of CNC feed drives (numpy, pandas, Dask)",
    long_description=(ROOT / "README.md").read_text(encoding="utf-8"),
    long_description_content_type="text/markdown",
    python_requires=">=3.8",
    packages=["feedid"],
    package_dir={"": "python"},
    package_data={"feedid": ["py.typed", "*.pyi"]},
    ext_modules=[Extension("feedid._feedid", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    install_requires=["numpy"],
    extras_require={"pandas": ["pandas"], "fleet": ["pandas", "dask", "distributed"]},
    options={"build": {"build_base": BUILD_BASE}, "egg_info": {"egg_base": BUILD_BASE}},
    zip_safe=False,
)
