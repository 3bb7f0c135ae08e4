"""Shared helpers of the Python tests."""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

import edgewise as ew

SAMPLES = os.environ.get("EW_SAMPLE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "samples"))
EXAMPLES = os.environ.get("EW_EXAMPLES_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "examples"))
CLI = os.environ.get("EW_CLI")
RENDER = os.path.join(SAMPLES, "cornell", "f0001_spp0004.exr")
REFERENCE = os.path.join(SAMPLES, "cornell", "f0001_ref1024.exr")


def read_image(path, output="color", **params):
    """Pixels of a file through a read -> output graph."""
    g = ew.Graph()
    r = g.add("read", path=path, **params)
    g.add("output", id="o", image=r[output])
    g.run()
    return g.output("o")


def run(cmd, **kw):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, **kw)


class TempDirTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="ew_pytest_")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def path(self, name):
        return os.path.join(self.tmp, name)


def python():
    return sys.executable


__all__ = ["np", "ew", "SAMPLES", "EXAMPLES", "CLI", "RENDER", "REFERENCE", "read_image", "run", "TempDirTest",
           "python", "unittest"]
