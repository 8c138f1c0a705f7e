"""modbus-server against real peers: the PLC emulator (pymodbus client) drives
trigger -> poll status -> read poses -> acknowledge against
`hnnstereo serve --robot modbus-server://127.0.0.1:0 --replay ...`, and mbpoll (a separate
Modbus master, as a commissioning engineer uses it) reads the same registers from the shell.
"""
import json
import os
import re
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import Plc, RESULT_READY, HEARTBEAT  # noqa: E402

# (id, x, y, height, yaw): the pose registers must list them tallest first.
OBJECTS = [(1, 100.0, -50.0, 30.0, 10.0), (2, -120.25, 80.5, 55.5, -45.0),
           (3, 0.0, 150.0, 42.0, 89.5)]
EXPECTED = [(-120.25, 80.5, 55.5, -45.0), (0.0, 150.0, 42.0, 89.5),
            (100.0, -50.0, 30.0, 10.0)]
CYCLES = 5


def close_enough(pose, expected):
    return all(abs(a - b) <= 0.011 for a, b in zip(pose, expected))


def mbpoll(port, args, timeout=10):
    """Runs mbpoll once against 127.0.0.1:PORT; returns {reference: value}."""
    command = ["mbpoll", "-m", "tcp", "-0", "-1", "-p", str(port)] + args + ["127.0.0.1"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    check(result.returncode == 0, "%s failed: %s%s" % (" ".join(command), result.stdout,
                                                        result.stderr))
    values = {int(m.group(1)): int(m.group(2))
              for m in re.finditer(r"^\[(\d+)\]:\s+(-?\d+)", result.stdout, re.M)}
    check(values, "no values in mbpoll output: " + result.stdout)
    return values


def main():
    work = peerlib.scratch_dir("modbus-server")
    frame, objects, report = (os.path.join(work, n) for n in
                              ("frame.yml", "objects.json", "report.json"))
    peerlib.write_frame(frame)
    peerlib.write_objects(objects, OBJECTS)
    serve = peerlib.Serve(["--frame", frame, "--robot", "modbus-server://127.0.0.1:0",
                           "--replay", objects, "--cycles", str(CYCLES), "--heartbeat", "100",
                           "--report", report])
    try:
        check(serve.link.startswith("modbus-server://127.0.0.1:"), "link line: " + serve.link)
        _, port = serve.host_port()
        check(port > 0, "port 0 must be replaced by the bound port: " + serve.link)
        plc = Plc(port)

        # Heartbeat: +1 each 100 ms. Two beats waited for (a loaded machine delays them), and no
        # more than the period allows in the time taken.
        start = time.time()
        first = second = plc.read(HEARTBEAT)[0]
        while (second - first) % 65536 < 2 and time.time() - start < 30:
            time.sleep(0.05)
            second = plc.read(HEARTBEAT)[0]
        elapsed = time.time() - start
        check(2 <= (second - first) % 65536 <= elapsed / 0.1 + 1,
              "heartbeat %d -> %d in %.2f s" % (first, second, elapsed))

        for i in range(CYCLES - 1):
            request = 100 + i
            status, poses = plc.cycle(request)
            check(status == RESULT_READY, "cycle %d: status %d" % (i, status))
            check(len(poses) == len(EXPECTED), "cycle %d: %d poses" % (i, len(poses)))
            for pose, expected in zip(poses, EXPECTED):
                check(close_enough(pose, expected), "cycle %d: pose %s, expected %s (tallest "
                      "first)" % (i, pose, expected))

        # The last cycle: mbpoll reads the result before the PLC acknowledges it.
        request = 4242
        plc.trigger(request)
        status, poses = plc.wait_result(request)
        check(status == RESULT_READY and len(poses) == 3, "last cycle: %d, %s" % (status, poses))
        header = mbpoll(port, ["-t", "4", "-r", "10", "-c", "4"])
        check(header[11] == RESULT_READY and header[12] == request and header[13] == 3,
              "mbpoll registers 10..13: %s" % header)
        words = mbpoll(port, ["-t", "4:int", "-B", "-r", "20", "-c", "4"])
        # 32-bit values, high word first: x, y, z in 0.01 mm, yaw in 0.001 degree.
        expected_words = {20: -12025, 22: 8050, 24: 5550, 26: -45000}
        check(words == expected_words, "mbpoll pose 0: %s, expected %s" % (words, expected_words))
        plc.acknowledge()  # the last cycle: serve exits once it has consumed it
        plc.close()

        code = serve.wait(timeout=30)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)))
        out = "".join(serve.stdout)
        check(len(re.findall(r"^cycle \d+", out, re.M)) == CYCLES, "cycle lines: " + out)
        with open(report) as f:
            counters = json.load(f)
        link = counters["link"]
        check(counters["cycles"] == CYCLES, "report cycles: %s" % counters)
        check(counters["poses_published"] == 3 * CYCLES, "report poses: %s" % counters)
        check(counters["ack_timeouts"] == 0 and counters["peer_lost"] == 0, "report: %s" % counters)
        check(link["triggers"] == CYCLES and link["duplicate_triggers"] == 0 and
              link["malformed"] == 0 and link["poses_sent"] == 3 * CYCLES and
              link["cycles_published"] == CYCLES and link["dropped_on_reconnect"] == 0,
              "link counters: %s" % link)
        check(link["connections"] == 3, "PLC + two mbpoll connections: %s" % link)
        print("OK: %d cycles, poses tallest first, sequence echoed, mbpoll read %s" %
              (CYCLES, words))
    finally:
        serve.kill()


if __name__ == "__main__":
    main()
