"""The install stories of python/README.md, as a user runs them: pip from a
built clone (offline, Debian's pip, into a venv) and `cmake --install`,
then `import edgewise` from another directory — the clone's parent, where
the clone's own folder would otherwise be an empty namespace package."""
import os
import shutil
import subprocess
import sys

from ewtest import TempDirTest, run, unittest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BUILD = os.environ.get("EW_BUILD_DIR")
CMAKE = os.environ.get("EW_CMAKE", "cmake")
CHECK = "import edgewise as ew; print(ew.version()); print(ew.library_dir()); print(ew.__file__)"


def clean_env():
    env = dict(os.environ)
    for k in ("PYTHONPATH", "EDGEWISE_LIB", "VIRTUAL_ENV"):
        env.pop(k, None)
    return env


class TestInstall(TempDirTest):
    def test_pip_install_from_the_clone(self):
        if not BUILD or os.path.realpath(os.path.join(BUILD, "lib")) != os.path.realpath(os.path.join(ROOT, "build", "lib")):
            self.skipTest("pip records the clone's build/lib; this build is elsewhere (%s)" % BUILD)
        venv = self.path("venv")
        r = run([sys.executable, "-m", "venv", "--system-site-packages", venv])
        if r.returncode != 0:
            self.skipTest("no venv module: %s" % r.stderr.strip()[-200:])
        pip = os.path.join(venv, "bin", "pip")
        r = run([pip, "install", "--no-build-isolation", "--no-index", os.path.join(ROOT, "python")], env=clean_env())
        self.assertEqual(r.returncode, 0, r.stdout[-800:] + r.stderr[-800:])
        r = run([os.path.join(venv, "bin", "python"), "-c", CHECK], cwd=os.path.dirname(ROOT), env=clean_env())
        self.assertEqual(r.returncode, 0, r.stderr)
        version, libdir, where = r.stdout.split("\n")[:3]
        self.assertRegex(version, r"^\d+\.\d+\.\d+$")
        self.assertTrue(where.startswith(venv), where)
        self.assertEqual(os.path.realpath(libdir), os.path.realpath(os.path.join(BUILD, "lib")))

    def test_cmake_install(self):
        if not BUILD or not shutil.which(CMAKE):
            self.skipTest("no build directory or cmake")
        prefix = self.path("prefix")
        r = run([CMAKE, "--install", BUILD, "--prefix", prefix])
        self.assertEqual(r.returncode, 0, r.stdout[-800:] + r.stderr[-800:])
        found = [os.path.join(d, "edgewise") for d, sub, _ in os.walk(prefix) if "edgewise" in sub and
                 os.path.exists(os.path.join(d, "edgewise", "__init__.py"))]
        self.assertEqual(len(found), 1, found)
        env = clean_env()
        env["PYTHONPATH"] = os.path.dirname(found[0])
        r = run([sys.executable, "-c", CHECK], cwd="/", env=env)
        self.assertEqual(r.returncode, 0, r.stderr)
        version, libdir, where = r.stdout.split("\n")[:3]
        self.assertTrue(os.path.realpath(libdir).startswith(os.path.realpath(prefix)), libdir)
        self.assertTrue(where.startswith(prefix), where)


if __name__ == "__main__":
    unittest.main()
