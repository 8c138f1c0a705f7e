"""modbus-server under faults, against `hnnstereo serve`: a PLC killed mid-cycle and
reconnecting (every acknowledged request delivered exactly once, no pose duplicated or lost),
malformed requests (bad command value, reads/writes beyond the map, a non-Modbus byte stream,
a frame cut short), a slow PLC (longer than --io-timeout between steps), poses outside the
workspace (never written). serve must survive all of it and exit 0 on the PLC's stop.
"""
import json
import os
import socket
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import (Plc, COMMAND, STATUS, POSE_COUNT, FIRST_POSE,  # noqa: E402
                          WORDS_PER_POSE, RESULT_READY, int16)

EMULATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plc_emulator.py")
OBJECTS = [(1, 50.0, 60.0, 20.0, 5.0), (2, -70.0, 30.0, 45.0, -30.0)]
EXPECTED = [(-70.0, 30.0, 45.0, -30.0), (50.0, 60.0, 20.0, 5.0)]
REGISTERS = 20 + 8 * 16  # serve's default --max-poses 16


def expect_poses(poses, expected, what):
    check(len(poses) == len(expected), "%s: %d poses, expected %d" % (what, len(poses),
                                                                      len(expected)))
    for pose, want in zip(poses, expected):
        check(all(abs(a - b) <= 0.011 for a, b in zip(pose, want)),
              "%s: pose %s, expected %s" % (what, pose, want))


def killed_plc(port, request, mode):
    """A PLC process that triggers `request` and is SIGKILLed (no acknowledge, no close)."""
    result = subprocess.run([sys.executable, EMULATOR, str(port), str(request), mode],
                            capture_output=True, text=True, timeout=30)
    check(result.returncode == -9, "the PLC process was not killed: %d %s" %
          (result.returncode, result.stderr))
    return result.stdout


def start_serve(work, name, objects, extra=()):
    frame = os.path.join(work, name + "-frame.yml")
    replay = os.path.join(work, name + "-objects.json")
    report = os.path.join(work, name + "-report.json")
    peerlib.write_frame(frame)
    peerlib.write_objects(replay, objects)
    serve = peerlib.Serve(["--frame", frame, "--robot", "modbus-server://127.0.0.1:0",
                           "--replay", replay, "--report", report] + list(extra))
    return serve, report


def finish(serve, report, plc):
    plc.stop()
    code = serve.wait(timeout=30)
    stderr = "".join(serve.stderr)
    check(code == 0, "serve exit %d: %s" % (code, stderr))
    check("terminate" not in stderr and "Segmentation" not in stderr, "serve: " + stderr)
    with open(report) as f:
        return json.load(f)


def expect_exception(response, code, what):
    check(response.isError() and getattr(response, "exception_code", None) == code,
          "%s: expected Modbus exception %d, got %s" % (what, code, response))


def kill_and_reconnect(work):
    # The acknowledge timeout far above any stall: a PLC process that reads its result and is
    # killed must count as a lost peer, not as an acknowledge timeout. Two CI runs on a loaded
    # 2-core machine reported ack_timeouts 1, peer_lost 1; the second (with this 60 s timeout)
    # showed the cause: the PLC reconnected and triggered again before serve began waiting for
    # the acknowledge, and that new trigger was taken for an unacknowledged result. Fixed in
    # robot/modbus_link.cc; tests/robot/modbus_link_test.cc reproduces the order.
    serve, report = start_serve(work, "kill", OBJECTS,
                                ["--io-timeout", "300", "--ack-timeout", "60"])
    try:
        _, port = serve.host_port()
        delivered = {}  # request -> poses, acknowledged

        # 1. Killed after reading the result: the reconnecting PLC finds no stale result and
        #    triggers the same request again.
        out = killed_plc(port, 1, "die-after-result")
        check(out.startswith("result 2 2"), "killed PLC saw: " + out)
        plc = Plc(port)
        status, _, count = plc.read(STATUS, 3)
        check(status == 0 and count == 0, "after the reconnect: status %d, %d poses (the "
              "unacknowledged result must be dropped)" % (int16(status), count))
        status, poses = plc.cycle(1)
        check(status == RESULT_READY, "retry of request 1: status %d" % status)
        delivered[1] = poses
        plc.close()

        # 2. Killed right after the trigger: whichever way the race goes, the reconnecting PLC
        #    gets exactly one result for request 2.
        killed_plc(port, 2, "die-after-trigger")
        plc = Plc(port)
        status, poses = plc.cycle(2)
        check(status == RESULT_READY, "retry of request 2: status %d" % status)
        delivered[2] = poses

        for request in (3, 4):
            status, poses = plc.cycle(request)
            check(status == RESULT_READY, "request %d: status %d" % (request, status))
            delivered[request] = poses
        plc.wait_consumed()
        for request, poses in delivered.items():
            expect_poses(poses, EXPECTED, "request %d" % request)
        counters = finish(serve, report, plc)
        link = counters["link"]
        dropped = link["dropped_on_reconnect"]
        check(dropped in (1, 2), "dropped_on_reconnect %d: %s" % (dropped, counters))
        # Every served trigger published 2 poses; retries after a drop are new cycles, a retry
        # of a still-pending result is a duplicate.
        check(counters["cycles"] == 4 + dropped and link["triggers"] == 4 + dropped and
              link["duplicate_triggers"] == 2 - dropped, "cycles/duplicates: %s" % counters)
        check(counters["poses_published"] == 2 * counters["cycles"] and
              link["poses_sent"] == counters["poses_published"], "poses: %s" % counters)
        check(counters["peer_lost"] == 2 and counters["stopped"], "report: %s" % counters)
        print("kill/reconnect: 4 requests acknowledged once each, %d results dropped on "
              "reconnect, report %s" % (dropped, counters))
    finally:
        serve.kill()


def malformed_and_slow(work):
    serve, report = start_serve(work, "malformed", OBJECTS,
                                ["--io-timeout", "300", "--ack-timeout", "5"])
    try:
        _, port = serve.host_port()
        plc = Plc(port)
        # A command value the protocol does not know.
        plc.write(COMMAND, 7)
        deadline = time.time() + 5
        while int16(plc.read(STATUS)[0]) != -4:
            check(time.time() < deadline, "status -4 (malformed) not shown")
            time.sleep(0.01)
        check(plc.read(COMMAND)[0] == 0, "the malformed command was not cleared")

        # Beyond the map, too many registers, a table this server does not have.
        client = plc.client
        expect_exception(client.read_holding_registers(REGISTERS - 2, 4, slave=1), 2,
                         "read past the end")
        expect_exception(client.write_registers(REGISTERS, [1, 2], slave=1), 2,
                         "write past the end")
        expect_exception(client.write_register(REGISTERS + 100, 1, slave=1), 2,
                         "write single past the end")
        expect_exception(client.read_holding_registers(0, 126, slave=1), 3,
                         "read of 126 registers")
        expect_exception(client.read_coils(0, 8, slave=1), 2, "read coils")

        # Not Modbus at all, and a frame cut short (longer than --io-timeout).
        with socket.create_connection(("127.0.0.1", port), timeout=5) as raw:
            raw.sendall(b"GET / HTTP/1.0\r\n\r\n" * 4)
            raw.settimeout(3)
            try:
                raw.recv(256)
            except (socket.timeout, ConnectionResetError):
                pass
        with socket.create_connection(("127.0.0.1", port), timeout=5) as raw:
            raw.sendall(b"\x00\x01\x00")
            time.sleep(0.8)

        # Still serving: a normal cycle clears the error status.
        status, poses = plc.cycle(10)
        check(status == RESULT_READY, "after malformed requests: status %d" % status)
        expect_poses(poses, EXPECTED, "after malformed requests")
        plc.wait_consumed()

        # A slow PLC: 0.6 s (twice --io-timeout) between the steps of a cycle.
        plc.trigger(11)
        time.sleep(0.6)
        # Ready with request 11's two poses (waited for: a loaded machine may take longer).
        status, poses = plc.wait_result(11)
        check(status == RESULT_READY and len(poses) == 2,
              "slow PLC: status %d, %d poses" % (status, len(poses)))
        time.sleep(0.6)
        expect_poses(plc.wait_result(11)[1], EXPECTED, "slow PLC")
        time.sleep(0.6)
        plc.acknowledge()
        plc.wait_consumed()

        counters = finish(serve, report, plc)
        link = counters["link"]
        check(counters["cycles"] == 2 and counters["ack_timeouts"] == 0 and
              counters["peer_lost"] == 0, "report: %s" % counters)
        check(link["malformed"] == 1 and link["poses_sent"] == 4, "link: %s" % link)
        print("malformed/slow: exceptions answered, serve kept serving, report %s" % counters)
    finally:
        serve.kill()


def outside_workspace(work):
    # x = 1000 mm is outside the workspace box (+-400) and beyond reach: never written.
    serve, report = start_serve(work, "outside", [(1, 1000.0, 0.0, 80.0, 0.0),
                                                  (2, 100.0, -100.0, 30.0, 15.0)])
    try:
        _, port = serve.host_port()
        plc = Plc(port)
        status, poses = plc.cycle(1)
        check(status == RESULT_READY, "one inside: status %d" % status)
        expect_poses(poses, [(100.0, -100.0, 30.0, 15.0)], "one inside")
        plc.wait_consumed()
        plc.trigger(2)
        plc.wait_result(2)
        words = plc.read(FIRST_POSE, 64) + plc.read(FIRST_POSE + 64, REGISTERS - FIRST_POSE - 64)
        check(words[WORDS_PER_POSE:] == [0] * (len(words) - WORDS_PER_POSE),
              "registers after the admitted pose are not empty: %s" % words[:32])
        plc.acknowledge()
        plc.wait_consumed()
        counters = finish(serve, report, plc)
        check(counters["refused"] == 2 and counters["poses_published"] == 2,
              "report: %s" % counters)
    finally:
        serve.kill()

    serve, report = start_serve(work, "all-outside", [(1, 1000.0, 0.0, 80.0, 0.0),
                                                      (2, 0.0, 0.0, 900.0, 0.0)])
    try:
        _, port = serve.host_port()
        plc = Plc(port)
        status, poses = plc.cycle(1)
        check(status == -3 and poses == [], "all refused: status %d, %s" % (status, poses))
        check(plc.read(POSE_COUNT)[0] == 0, "all refused: pose count")
        plc.wait_consumed()
        counters = finish(serve, report, plc)
        check(counters["refused"] == 2 and counters["poses_published"] == 0,
              "report: %s" % counters)
        print("outside the workspace: refused poses never written; status -3 when all were")
    finally:
        serve.kill()


def main():
    work = peerlib.scratch_dir("modbus-faults")
    kill_and_reconnect(work)
    malformed_and_slow(work)
    outside_workspace(work)
    print("OK")


if __name__ == "__main__":
    main()
