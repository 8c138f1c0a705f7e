"""serial: the thesis RS-232 link through a socat pty pair, read by pyserial on the far end.

serve --robot serial:A?baud=2400&flow=none --replay OBJECTS.json --cycles 2 with the thesis
frame (x_r = 600 - X, y_r = 400 - Y mm). The reader parses the CR-terminated commands and checks
them on its own: the sequence of commands, SP from the speed, and its own forward kinematics
from each PS line's pulses back to the expected grip-point positions. One object is within the
workspace but beyond the arm: none of its lines may appear.
"""
import json
import os
import shutil
import subprocess
import sys
import threading
import time

import serial  # python3-serial

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from arm_kinematics import forward, parse_ps, roll_difference  # noqa: E402
from peerlib import Serve, check, scratch_dir, write_frame, write_objects  # noqa: E402

# World (X, Y) mm, height, yaw; robot = (600 - X, 400 - Y, height), yaw unchanged (half turn).
OBJECTS = [(1, 300.0, 350.0, 40.0, 20.0),   # robot (300, 50, 40)
           (2, 350.0, 460.0, 30.0, -10.0),  # robot (250, -60, 30)
           (3, 50.0, 400.0, 60.0, 0.0)]     # robot (550, 0, 60): in the workspace, out of reach
REACHABLE = [(300.0, 50.0, 40.0, 20.0), (250.0, -60.0, 30.0, -10.0)]  # tallest first
CYCLES = 2
SPEED_STEP = 2  # the planner's default speed 0.2 of 9 steps
PICK_SHAPE = ["SP", "PS", "MO 1", "GO", "PS", "MO 1", "GC", "GF 1", "PS", "MO 1", "PS", "MO 1",
              "GF 0", "GO", "PS", "MO 1"]
TOLERANCE_MM = 0.6  # half a pulse per joint, through the FK


def expect_at(line, xyz, roll, what):
    pulses = parse_ps(line)
    (x, y, z), pitch, got_roll = forward(pulses)
    error = max(abs(x - xyz[0]), abs(y - xyz[1]), abs(z - xyz[2]))
    check(error < TOLERANCE_MM, "%s: FK of %r is (%.2f, %.2f, %.2f), want %r" % (what, line, x, y,
                                                                                   z, xyz))
    check(abs(pitch - 180.0) < 0.2, "%s: tool not pointing down (pitch %.2f)" % (what, pitch))
    if roll is not None:
        check(roll_difference(got_roll, roll) < 0.2, "%s: roll %.2f, want %.2f" % (what, got_roll,
                                                                                 roll))
    check(pulses[5] == 0, "%s: a5 must be 0" % what)
    return error


def main():
    if shutil.which("socat") is None:
        check(False, "socat is not installed")
    folder = scratch_dir("serial-thesis")
    end_a = os.path.join(folder, "ttyA")
    end_b = os.path.join(folder, "ttyB")
    socat = subprocess.Popen(["socat", "pty,raw,echo=0,link=" + end_a,
                              "pty,raw,echo=0,link=" + end_b],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    serve = None
    try:
        deadline = time.time() + 10
        while not (os.path.exists(end_a) and os.path.exists(end_b)) and time.time() < deadline:
            time.sleep(0.05)
        check(os.path.exists(end_a) and os.path.exists(end_b), "socat made no pty pair")
        reader = serial.Serial(end_b, baudrate=2400, bytesize=serial.EIGHTBITS,
                               parity=serial.PARITY_NONE, stopbits=serial.STOPBITS_TWO,
                               timeout=0.1)
        received = bytearray()
        stop_reading = threading.Event()

        def pump():
            while not stop_reading.is_set():
                try:
                    received.extend(reader.read(4096))
                except serial.SerialException:  # the other end went away
                    time.sleep(0.05)
        thread = threading.Thread(target=pump, daemon=True)
        thread.start()

        frame = os.path.join(folder, "frame.yml")
        write_frame(frame, robot_from_world=[[-1, 0, 0, 600], [0, -1, 0, 400], [0, 0, 1, 0],
                                             [0, 0, 0, 1]],
                    workspace_min=(100, -300, 0), workspace_max=(600, 300, 450))
        objects = os.path.join(folder, "objects.json")
        write_objects(objects, OBJECTS)
        report = os.path.join(folder, "report.json")
        start = time.time()
        serve = Serve(["--frame", frame, "--robot", "serial:%s?baud=2400&flow=none" % end_a,
                       "--replay", objects, "--cycles", str(CYCLES), "--report", report])
        check(serve.link == "serial:%s?baud=2400&flow=none" % end_a, "link line: %r" % serve.link)
        code = serve.wait(timeout=60)
        elapsed = time.time() - start
        check(code == 0, "serve exit %r: %s" % (code, "".join(serve.stderr)))
        # serve has exited, so every command is in the pty: wait until they are read (a loaded
        # machine may take a while), then take whatever else is there.
        want = CYCLES * (len(REACHABLE) * len(PICK_SHAPE) + 2)
        deadline = time.time() + 30
        while received.count(b"\r") < want and time.time() < deadline:
            time.sleep(0.05)
        stop_reading.set()
        thread.join(timeout=2)
        received.extend(reader.read(reader.in_waiting))
        reader.close()

        text = received.decode("ascii")
        check("\n" not in text, "LF on the wire: commands are CR-terminated")
        check(text.endswith("\r"), "the last command is not CR-terminated: %r" % text[-20:])
        lines = text.split("\r")[:-1]
        per_cycle = len(REACHABLE) * len(PICK_SHAPE) + 2
        check(len(lines) == CYCLES * per_cycle,
              "%d lines, want %d: %r" % (len(lines), CYCLES * per_cycle, lines))
        worst = 0.0
        for cycle in range(CYCLES):
            block = lines[cycle * per_cycle:(cycle + 1) * per_cycle]
            for index, (x, y, top, yaw) in enumerate(REACHABLE):
                pick = block[index * len(PICK_SHAPE):(index + 1) * len(PICK_SHAPE)]
                what = "cycle %d pick %d" % (cycle + 1, index + 1)
                for got, shape in zip(pick, PICK_SHAPE):
                    check(got == shape or (shape in ("SP", "PS") and got.startswith(shape + " ")),
                          "%s: %r where %r belongs: %r" % (what, got, shape, pick))
                check(pick[0] == "SP %d" % SPEED_STEP, "%s: %r, want SP %d" % (what, pick[0],
                                                                                 SPEED_STEP))
                drop = (200.0, -200.0 - 50.0 * index)
                worst = max(worst,
                            expect_at(pick[1], (x, y, top + 10), yaw, what + " above"),
                            expect_at(pick[4], (x, y, top - 20), yaw, what + " grip"),
                            expect_at(pick[8], (x, y, top + 30), yaw, what + " lift"),
                            expect_at(pick[10], (drop[0], drop[1], top - 20), None, what + " drop"),
                            expect_at(pick[14], (drop[0], drop[1], 100.0), None,
                                      what + " drop lift"))
            aside = block[-2:]
            worst = max(worst, expect_at(aside[0], (100.5, 349.0, 80.0), None,
                                         "cycle %d aside" % (cycle + 1)))
            check(aside[1] == "MO 1", "aside not followed by MO 1: %r" % aside)
        with open(report) as f:
            counters = json.load(f)
        check(counters["cycles"] == CYCLES, "report: %r" % counters)
        check(counters["link"]["poses_sent"] == CYCLES * len(REACHABLE),
              "poses sent (the unreachable one must not count): %r" % counters["link"])
        check(counters["poses_published"] == CYCLES * len(REACHABLE) and
              counters["link"]["transport_refused"] == CYCLES and
              counters["refused"] == CYCLES * (len(OBJECTS) - len(REACHABLE)),
              "the loop must count the arm's refusal as refused, not published: %r" % counters)
        check(all(", %d sent," % len(REACHABLE) in line
                  for line in serve.stdout if line.startswith("cycle ")),
              "cycle lines must say %d sent: %r" % (len(REACHABLE), serve.stdout))
        check(any("cannot reach" in line for line in serve.stderr),
              "the unreachable pick was not logged: %r" % serve.stderr)
        print("serial thesis: %d cycles, %d lines, %d bytes in %.2f s; worst FK error %.3f mm"
              % (CYCLES, len(lines), len(received), elapsed, worst))
    finally:
        if serve is not None:
            serve.kill()
        socat.terminate()
        try:
            socat.wait(timeout=5)
        except subprocess.TimeoutExpired:
            socat.kill()


if __name__ == "__main__":
    main()
