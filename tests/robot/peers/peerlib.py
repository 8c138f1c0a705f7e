"""Shared helpers for the robot-link tests against real peers (run by CTest with /usr/bin/python3).

Environment (set by tests/robot/CMakeLists.txt): HNNSTEREO_BINARY (the hnnstereo executable),
HNNSTEREO_SOURCE_DIR, HNNSTEREO_TEST_TMP (a scratch folder in the build tree).
"""
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time

BINARY = os.environ.get("HNNSTEREO_BINARY", "build/hnnstereo")
TMP_ROOT = os.environ.get("HNNSTEREO_TEST_TMP", tempfile.gettempdir())


def scratch_dir(name):
    """A fresh folder for one test under HNNSTEREO_TEST_TMP."""
    os.makedirs(TMP_ROOT, exist_ok=True)
    return tempfile.mkdtemp(prefix=name + "-", dir=TMP_ROOT)


def render_scene(seed, out):
    """`hnnstereo render --seed SEED --out OUT`; returns the true parts of truth.json."""
    render = subprocess.run([BINARY, "render", "--seed", str(seed), "--out", out],
                            capture_output=True, text=True, timeout=120)
    check(render.returncode == 0, "render failed: " + render.stdout + render.stderr)
    with open(os.path.join(out, "truth.json")) as f:
        return json.load(f)["objects"]


def write_frame(path, robot_from_world=None, workspace_min=(-400, -400, 0),
                workspace_max=(400, 400, 500), rms_mm=0.0):
    """FRAME.yml in OpenCV FileStorage YAML (ARCHITECTURE.md). Identity transform by default."""
    m = robot_from_world or [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    flat = ", ".join(repr(float(v)) for row in m for v in row)

    def vec(v):
        return ("!!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ %s ]\n"
                % ", ".join(repr(float(x)) for x in v))
    with open(path, "w") as f:
        f.write("%YAML:1.0\n---\n")
        f.write("robot_from_world: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n"
                "   data: [ %s ]\n" % flat)
        f.write("workspace_min: " + vec(workspace_min))
        f.write("workspace_max: " + vec(workspace_max))
        f.write("rms_mm: %r\n" % float(rms_mm))


def write_objects(path, objects):
    """OBJECTS.json as `pick` writes it; objects = [(id, x, y, height_mm, yaw_deg), ...]
    (the top-face centre is (x, y, height))."""
    items = [{"id": i, "centroid": [x, y, h], "height": h, "yaw_deg": yaw, "points": 100}
             for (i, x, y, h, yaw) in objects]
    with open(path, "w") as f:
        json.dump({"units": "mm", "objects": items}, f)


class Serve:
    """`hnnstereo serve ...` in the background. Reads its stdout on a thread; `link` is the
    text after the first 'link: ' line (the transport's Describe(), with the bound port)."""

    def __init__(self, args, startup_timeout=20.0):
        self.proc = subprocess.Popen([BINARY, "serve"] + list(args), stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.lines = queue.Queue()
        self.stdout = []
        self.stderr = []
        self.pumps = [
            threading.Thread(target=self._pump, args=(self.proc.stdout, self.stdout, True),
                             daemon=True),
            threading.Thread(target=self._pump, args=(self.proc.stderr, self.stderr, False),
                             daemon=True)]
        for pump in self.pumps:
            pump.start()
        self.link = None
        deadline = time.time() + startup_timeout
        while time.time() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            if line.startswith("link: "):
                self.link = line[len("link: "):].strip()
                break
        if self.link is None:
            self.kill()
            raise RuntimeError("serve did not start: " + "".join(self.stderr))

    def _pump(self, stream, sink, to_queue):
        for line in stream:
            sink.append(line)
            if to_queue:
                self.lines.put(line)

    def host_port(self):
        """(host, port) of a //HOST:PORT link."""
        rest = self.link.split("//", 1)[1]
        host, port = rest.rsplit(":", 1)
        return host, int(port)

    def wait(self, timeout):
        """Exit code, or raises subprocess.TimeoutExpired."""
        code = self.proc.wait(timeout=timeout)
        for pump in self.pumps:  # drained: both pipes reach end of file once serve has exited
            pump.join(timeout=30)
        return code

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def check(condition, message):
    """Fail the test with a one-line message (CTest shows stderr)."""
    if not condition:
        print("FAIL: " + message, file=sys.stderr)
        sys.exit(1)
