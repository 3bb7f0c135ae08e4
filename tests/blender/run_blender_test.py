"""Run a Blender test script headless; exit 77 (skipped) when blender is not installed.

    python3 run_blender_test.py SCRIPT [ARGS...]     ($BLENDER overrides the executable)
"""
import os
import shutil
import subprocess
import sys

blender = os.environ.get("BLENDER") or shutil.which("blender")
if not blender or not os.path.exists(blender):
    print("skipped: blender is not installed (apt-get install blender, or set $BLENDER)")
    sys.exit(77)
cmd = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", sys.argv[1], "--"] + sys.argv[2:]
print(" ".join(cmd))
sys.stdout.flush()
sys.exit(subprocess.call(cmd))
