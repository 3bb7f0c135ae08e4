"""Run a Blender test script headless; exit 77 (skipped) when blender is not installed.

    python3 run_blender_test.py [--gui] SCRIPT [ARGS...]     ($BLENDER overrides the executable)

--gui runs Blender with windows under xvfb-run (skipped without it) instead of -b.
"""
import os
import shutil
import subprocess
import sys

blender = os.environ.get("BLENDER") or shutil.which("blender")
if not blender or not os.path.exists(blender):
    print("skipped: blender is not installed (apt-get install blender, or set $BLENDER)")
    sys.exit(77)
args = sys.argv[1:]
if args and args[0] == "--gui":
    # Blender with its windows, on a virtual X server (the user-visible path: F12 and Ctrl+F12 as render jobs)
    xvfb = shutil.which("xvfb-run")
    if not xvfb:
        print("skipped: xvfb-run is not installed (apt-get install xvfb) for the windowed Blender test")
        sys.exit(77)
    args = args[1:]
    # --enable-event-simulate: the script presses keys (Window.event_simulate); real input is ignored
    cmd = [xvfb, "-a", "-s", "-screen 0 1280x800x24", blender, "--factory-startup", "-p", "0", "0", "1280", "800",
           "--enable-event-simulate", "--python-exit-code", "1", "--python", args[0], "--"] + args[1:]
else:
    cmd = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", args[0], "--"] + args[1:]
print(" ".join(cmd))
sys.stdout.flush()
sys.exit(subprocess.call(cmd))
