"""The build step of the Python package: CMake builds the module _pwcontact
(PWCONTACT_BUILD_PYTHON, against the interpreter running this), which is
copied into the package. Everything else is in pyproject.toml."""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = pathlib.Path(self.build_temp).resolve() / "cmake"
        build.mkdir(parents=True, exist_ok=True)
        subprocess.run(
            ["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
             "-DPWCONTACT_BUILD_PYTHON=ON", "-DPWCONTACT_BUILD_TESTS=OFF", "-DPWCONTACT_BUILD_BENCH=OFF",
             "-DPWCONTACT_BUILD_CLI=OFF", "-DPWCONTACT_INSTALL=OFF", f"-DPython3_EXECUTABLE={sys.executable}"],
            check=True)
        jobs = str(os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build), "--target", "_pwcontact", "-j", jobs], check=True)
        built = next((build / "python" / "pwcontact").glob("_pwcontact*.so"))
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, target)


setup(ext_modules=[Extension("pwcontact._pwcontact", sources=[])], cmdclass={"build_ext": CMakeBuild})
