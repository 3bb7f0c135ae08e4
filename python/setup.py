"""Build hook of the pure-Python package (metadata: pyproject.toml).

The package loads libedgewise.so and libedgewise_nodes.so with ctypes. When
it is installed from a built clone (`pip install --no-build-isolation
./python`), this records the clone's build/lib in edgewise/_install.py, so
the installed package finds the libraries from any directory; $EDGEWISE_LIB
still comes first (edgewise/_lib.py)."""
import os

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))


class BuildPy(build_py):
    def run(self):
        build_py.run(self)
        libdir = os.path.join(os.path.dirname(HERE), "build", "lib")
        dirs = [libdir] if os.path.exists(os.path.join(libdir, "libedgewise_nodes.so")) else []
        if not dirs:
            self.announce("edgewise: no build/lib beside this package yet; set EDGEWISE_LIB when using it", 2)
        target = os.path.join(self.build_lib, "edgewise", "_install.py")
        with open(target, "w") as f:
            f.write("# written by python/setup.py at install time\nLIBRARY_DIRS = %r\n" % (dirs,))


setup(cmdclass={"build_py": BuildPy})
