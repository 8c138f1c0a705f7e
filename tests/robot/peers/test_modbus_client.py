"""modbus-client against a real peer: a pymodbus 3.0.0 TCP server plays the controller. It
triggers and acknowledges by writing its own registers; `hnnstereo serve --robot
modbus-client://...` polls them and writes the results and the heartbeat into them.
"""
import asyncio
import json
import logging
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import (COMMAND, REQUEST_SEQUENCE, HEARTBEAT, STATUS, RESULT_SEQUENCE,  # noqa
                          POSE_COUNT, FIRST_POSE, WORDS_PER_POSE, TRIGGER, ACKNOWLEDGE, STOP,
                          RESULT_READY, IDLE, int16, decode_poses)

from pymodbus.datastore import (ModbusSequentialDataBlock, ModbusServerContext,  # noqa: E402
                                ModbusSlaveContext)
from pymodbus.server import StartAsyncTcpServer  # noqa: E402

OBJECTS = [(1, 10.0, 20.0, 25.0, 0.0), (2, -200.0, -300.0, 60.0, -12.345),
           (3, 0.0, 0.0, 900.0, 0.0)]  # 3: above the workspace (z max 500): never written
EXPECTED = [(-200.0, -300.0, 60.0, -12.345), (10.0, 20.0, 25.0, 0.0)]
CYCLES = 3
REGISTERS = 20 + 8 * 16


class Controller:
    """A pymodbus TCP server on 127.0.0.1 (port chosen by the kernel) in a thread; the test
    reads and writes the same data block the server answers from."""

    def __init__(self):
        self.block = ModbusSequentialDataBlock(0, [0] * REGISTERS)
        store = ModbusSlaveContext(hr=self.block, zero_mode=True)
        self.context = ModbusServerContext(slaves=store, single=True)
        self.port = None
        started = threading.Event()
        threading.Thread(target=self._run, args=(started,), daemon=True).start()
        check(started.wait(10) and self.port, "pymodbus server did not start")

    def _run(self, started):
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)

        async def serve():
            server = await StartAsyncTcpServer(context=self.context,
                                               address=("127.0.0.1", 0), defer_start=True,
                                               loop=loop)
            task = asyncio.ensure_future(server.serve_forever())
            await server.serving
            self.port = server.server.sockets[0].getsockname()[1]
            started.set()
            await task
        loop.run_until_complete(serve())

    def get(self, address, count=1):
        return list(self.block.getValues(address, count))

    def set(self, address, values):
        self.block.setValues(address, values if isinstance(values, list) else [values])

    def wait_for(self, condition, what, timeout=10.0):
        deadline = time.time() + timeout
        while not condition():
            check(time.time() < deadline, "controller: timed out waiting for " + what)
            time.sleep(0.002)


def main():
    # pymodbus logs a client's disconnect as an error; it is the expected end of a session.
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    controller = Controller()
    work = peerlib.scratch_dir("modbus-client")
    frame, objects, report = (os.path.join(work, n) for n in
                              ("frame.yml", "objects.json", "report.json"))
    peerlib.write_frame(frame)
    peerlib.write_objects(objects, OBJECTS)
    serve = peerlib.Serve(["--frame", frame, "--robot",
                           "modbus-client://127.0.0.1:%d?poll_ms=5" % controller.port,
                           "--replay", objects, "--heartbeat", "50", "--report", report])
    try:
        check(serve.link == "modbus-client://127.0.0.1:%d" % controller.port,
              "link line: " + serve.link)
        controller.wait_for(lambda: controller.get(HEARTBEAT)[0] >= 3, "the heartbeat")
        for i in range(CYCLES):
            request = 7 + i
            controller.wait_for(lambda: controller.get(COMMAND)[0] == 0, "register 0 cleared")
            controller.set(REQUEST_SEQUENCE, request)
            controller.set(COMMAND, TRIGGER)
            controller.wait_for(lambda: controller.get(STATUS)[0] == RESULT_READY and
                                controller.get(RESULT_SEQUENCE)[0] == request,
                                "the result of request %d" % request)
            count = controller.get(POSE_COUNT)[0]
            check(count == len(EXPECTED), "cycle %d: %d poses" % (i, count))
            poses = decode_poses(controller.get(FIRST_POSE, count * WORDS_PER_POSE))
            for pose, expected in zip(poses, EXPECTED):
                check(all(abs(a - b) <= 0.011 for a, b in zip(pose, expected)),
                      "cycle %d: pose %s, expected %s" % (i, pose, expected))
            refused = controller.get(FIRST_POSE + count * WORDS_PER_POSE, WORDS_PER_POSE)
            check(refused == [0] * WORDS_PER_POSE, "the refused pose was written: %s" % refused)
            controller.set(COMMAND, ACKNOWLEDGE)
            controller.wait_for(lambda: controller.get(COMMAND)[0] == 0 and
                                controller.get(STATUS)[0] == IDLE and
                                controller.get(POSE_COUNT)[0] == 0, "the acknowledge consumed")
        controller.set(COMMAND, STOP)
        code = serve.wait(timeout=30)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)))
        with open(report) as f:
            counters = json.load(f)
        link = counters["link"]
        check(counters["cycles"] == CYCLES and counters["stopped"], "report: %s" % counters)
        check(counters["poses_published"] == 2 * CYCLES and counters["refused"] == CYCLES,
              "report: %s" % counters)
        check(link["connections"] == 1 and link["reconnects"] == 0 and
              link["triggers"] == CYCLES and link["poses_sent"] == 2 * CYCLES and
              link["malformed"] == 0, "link counters: %s" % link)
        check(controller.get(COMMAND)[0] == 0, "the stop was not consumed")
        print("OK: %d cycles as modbus-client, heartbeat %d, poses %s" %
              (CYCLES, controller.get(HEARTBEAT)[0], poses))
    finally:
        serve.kill()


if __name__ == "__main__":
    main()
