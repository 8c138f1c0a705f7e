"""Soak: 1,000 trigger cycles of the PLC emulator against `hnnstereo serve --robot
modbus-server://127.0.0.1:0`; none lost, none duplicated (every result echoes its request
sequence, with every pose). Prints the elapsed time and cycles/s (docs/robot_modbus.md).
"""
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import Plc, RESULT_READY  # noqa: E402

CYCLES = 1000
OBJECTS = [(1, 10.0, 10.0, 20.0, 1.0), (2, 20.0, -20.0, 40.0, -2.0),
           (3, -30.0, 30.0, 30.0, 3.0)]
EXPECTED = [(20.0, -20.0, 40.0, -2.0), (-30.0, 30.0, 30.0, 3.0), (10.0, 10.0, 20.0, 1.0)]
BUDGET_S = 120.0  # far below the CTest timeout; a typical run takes a few seconds


def main():
    work = peerlib.scratch_dir("modbus-soak")
    frame, objects, report = (os.path.join(work, n) for n in
                              ("frame.yml", "objects.json", "report.json"))
    peerlib.write_frame(frame)
    peerlib.write_objects(objects, OBJECTS)
    serve = peerlib.Serve(["--frame", frame, "--robot", "modbus-server://127.0.0.1:0",
                           "--replay", objects, "--cycles", str(CYCLES), "--report", report])
    try:
        _, port = serve.host_port()
        plc = Plc(port, poll_s=0.0005)
        start = time.time()
        for i in range(CYCLES):
            request = (i + 1) % 65536
            status, poses = plc.cycle(request)
            check(status == RESULT_READY and len(poses) == 3,
                  "cycle %d: status %d, %d poses" % (i, status, len(poses)))
            for pose, expected in zip(poses, EXPECTED):
                check(all(abs(a - b) <= 0.011 for a, b in zip(pose, expected)),
                      "cycle %d: pose %s, expected %s" % (i, pose, expected))
            check(time.time() - start < BUDGET_S, "soak exceeded %.0f s at cycle %d" %
                  (BUDGET_S, i))
        elapsed = time.time() - start
        code = serve.wait(timeout=30)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)))
        with open(report) as f:
            counters = json.load(f)
        link = counters["link"]
        check(counters["cycles"] == CYCLES and counters["poses_published"] == 3 * CYCLES and
              counters["ack_timeouts"] == 0 and counters["peer_lost"] == 0,
              "report: %s" % counters)
        check(link["triggers"] == CYCLES and link["duplicate_triggers"] == 0 and
              link["malformed"] == 0 and link["cycles_published"] == CYCLES and
              link["poses_sent"] == 3 * CYCLES and link["dropped_on_reconnect"] == 0,
              "link: %s" % link)
        print("soak: %d cycles in %.2f s = %.0f cycles/s (%.2f ms per cycle), none lost or "
              "duplicated" % (CYCLES, elapsed, CYCLES / elapsed, 1000.0 * elapsed / CYCLES))
    finally:
        serve.kill()


if __name__ == "__main__":
    main()
