"""vision-server: a URScript-style robot against `hnnstereo serve --replay`.

Identity frame, so a pick's robot position is the object's (x, y, height) in mm and its
orientation Rz(yaw) * Rx(180 deg). The robot sends TRIG and reads 7 floats as
socket_read_ascii_float(7) would; NEXT walks the cycle tallest first; STOP ends serve.
"""
import json
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peerlib import Serve, check, scratch_dir, write_frame, write_objects  # noqa: E402
from urscript_client import URSocket, expected_rotation_vector, same_rotation_vector  # noqa: E402

OBJECTS = [(1, 100.0, 50.0, 30.0, 20.0), (2, -150.0, 80.0, 60.0, -30.0),
           (3, 50.0, -120.0, 45.0, 0.0)]
TALLEST_FIRST = sorted(OBJECTS, key=lambda o: -o[3])


def check_pose(reply, obj, what):
    check(reply[0] == 7, "%s: socket_read_ascii_float(7) failed: %r" % (what, reply))
    st, x, y, z, rx, ry, rz = reply[1:]
    check(st == 1, "%s: status %r, want 1" % (what, st))
    _, ox, oy, height, yaw = obj
    check(abs(x - ox / 1000) < 1e-6 and abs(y - oy / 1000) < 1e-6 and abs(z - height / 1000) < 1e-6,
          "%s: position (%g, %g, %g) m, want object %d at (%g, %g, %g) mm"
          % (what, x, y, z, obj[0], ox, oy, height))
    want = expected_rotation_vector(yaw)
    check(same_rotation_vector((rx, ry, rz), want),
          "%s: rotation vector (%g, %g, %g), want +-%r" % (what, rx, ry, rz, want))


def main():
    folder = scratch_dir("vision-replay")
    frame = os.path.join(folder, "frame.yml")
    objects = os.path.join(folder, "objects.json")
    report = os.path.join(folder, "report.json")
    write_frame(frame)
    write_objects(objects, OBJECTS)
    serve = Serve(["--frame", frame, "--robot", "vision-server://127.0.0.1:0", "--replay", objects,
                   "--idle-limit", "30", "--report", report])
    try:
        check(serve.link.startswith("vision-server://127.0.0.1:"), "link line: %r" % serve.link)
        host, port = serve.host_port()
        check(port > 0, "ephemeral port not reported: %r" % serve.link)
        robot = URSocket(host, port)
        latencies = []
        for cycle in range(2):
            start = time.time()
            robot.send_line("TRIG")
            reply = robot.read_ascii_float(7)
            latencies.append(time.time() - start)
            check_pose(reply, TALLEST_FIRST[0], "cycle %d TRIG" % (cycle + 1))
            for index, obj in enumerate(TALLEST_FIRST[1:], start=2):
                robot.send_line("NEXT")
                check_pose(robot.read_ascii_float(7), obj, "cycle %d NEXT %d" % (cycle + 1, index))
            robot.send_line("NEXT")
            done = robot.read_ascii_float(7)
            check(done == [7, 0, 0, 0, 0, 0, 0, 0], "exhausted cycle: %r" % (done,))
        robot.send_line("STOP")
        code = serve.wait(timeout=15)
        check(code == 0, "serve exit %r: %s" % (code, "".join(serve.stderr)))
        cycle_lines = [line for line in serve.stdout if line.startswith("cycle ")]
        check(len(cycle_lines) == 2, "cycle lines: %r" % serve.stdout)
        with open(report) as f:
            counters = json.load(f)
        check(counters["cycles"] == 2 and counters["poses_published"] == 6,
              "report: %r" % counters)
        check(counters["stopped"] is True, "report: not stopped: %r" % counters)
        link = counters["link"]
        check(link["triggers"] == 2 and link["poses_sent"] == 6 and link["malformed"] == 0
              and link["connections"] == 1, "link counters: %r" % link)
        print("vision replay: 2 cycles x 3 poses; TRIG->reply %.1f / %.1f ms"
              % (latencies[0] * 1000, latencies[1] * 1000))
    finally:
        serve.kill()


if __name__ == "__main__":
    main()
