"""One client never delays another (issue 15), at the command line: `hnnstereo serve --replay`
with modbus-server and with vision-server, a PLC (the pymodbus PLC emulator) or a URScript-style
robot doing 30 cycles alone and then 30 more while hostile clients from other loopback
addresses (127.0.0.2-6) send garbage, an MBAP length of 65535, bad function codes, oversized
reads, out-of-map writes, overlong or malformed lines, trickle bytes, or hold connections open.
The acceptance bound: the 30 cycles with them within twice their time alone plus 1 s, every
pose right. Prints the figures (docs/robot.md, "Hostile clients").
"""
import os
import multiprocessing
import random
import socket
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import Plc, RESULT_READY  # noqa: E402
from urscript_client import URSocket  # noqa: E402

OBJECTS = [(1, 100.0, -50.0, 30.0, 10.0), (2, -120.25, 80.5, 55.5, -45.0)]
EXPECTED = [(-120.25, 80.5, 55.5, -45.0), (100.0, -50.0, 30.0, 10.0)]
CYCLES = 30
IP_BIND_ADDRESS_NO_PORT = getattr(socket, "IP_BIND_ADDRESS_NO_PORT", 24)  # linux/in.h


def mbap(pdu, length=None, transaction=1):
    """Messaging on TCP/IP Implementation Guide V1.0b 3.1.3: transaction, protocol 0, length,
    unit 1, then the PDU."""
    return struct.pack(">HHHB", transaction, 0, len(pdu) + 1 if length is None else length,
                       1) + pdu


READ_TWO = mbap(struct.pack(">BHH", 3, 10, 2))


class Crowd:
    """Hostile clients in threads of a child process (so that they do not compete with the
    PLC or robot of this process for Python's GIL), each reconnecting whenever the server
    closes it. add() all kinds, then start()."""

    def __init__(self, port):
        self.port = port
        self.stop = multiprocessing.Event()
        self.count = multiprocessing.Value("i", 0)
        self.kinds = []
        self.process = None

    def add(self, behaviour, count, source):
        self.kinds.append((behaviour, count, source))

    def start(self):
        self.process = multiprocessing.Process(target=self._main, daemon=True)
        self.process.start()

    @property
    def connections(self):
        return self.count.value

    def _main(self):
        random.seed(15)
        threads = []
        for behaviour, count, source in self.kinds:
            for i in range(count):
                thread = threading.Thread(target=self._run,
                                          args=(behaviour, "127.0.0.%d" % (source + i % 2)),
                                          daemon=True)
                thread.start()
                threads.append(thread)
        for thread in threads:
            thread.join()

    def _run(self, behaviour, source):
        while not self.stop.is_set():
            try:
                sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                sock.settimeout(0.2)
                # The port chosen at connect(), not bind(): cheaper with thousands in TIME_WAIT.
                sock.setsockopt(socket.IPPROTO_IP, IP_BIND_ADDRESS_NO_PORT, 1)
                sock.bind((source, 0))
                sock.connect(("127.0.0.1", self.port))
            except OSError:
                time.sleep(0.02)
                continue
            with self.count.get_lock():
                self.count.value += 1
            try:
                behaviour(sock, self.stop)
            except OSError:
                pass
            finally:
                sock.close()
            time.sleep(0.001)  # at most ~1000 reconnects/s per client (see hostile_clients.h)

    def close(self):
        self.stop.set()
        if self.process is not None:
            self.process.join(timeout=10)
            if self.process.is_alive():
                self.process.kill()


def hold_until_closed(sock, stop):
    while not stop.is_set():
        try:
            if sock.recv(512) == b"":
                return
        except socket.timeout:
            continue


def send_then_hold(payload):
    def behaviour(sock, stop):
        sock.sendall(payload)
        hold_until_closed(sock, stop)
    return behaviour


def garbage(sock, stop):
    sock.sendall(bytes(random.getrandbits(8) for _ in range(random.randint(1, 300))))


def request_loop(payload):
    def behaviour(sock, stop):
        while not stop.is_set():
            sock.sendall(payload)
            try:
                if not sock.recv(512):
                    return
            except socket.timeout:
                continue
    return behaviour


def trickle(payload):
    def behaviour(sock, stop):
        i = 0
        while not stop.is_set():
            sock.sendall(payload[i % len(payload):i % len(payload) + 1])
            i += 1
            stop.wait(0.15)
    return behaviour


def flood_without_reading(payload):
    def behaviour(sock, stop):
        burst = payload * 64
        while not stop.is_set():
            try:
                sock.sendall(burst)
            except socket.timeout:
                continue
    return behaviour


def timed(run):
    start = time.time()
    run()
    return time.time() - start


def modbus_server():
    work = peerlib.scratch_dir("hostile-modbus")
    frame, objects = os.path.join(work, "frame.yml"), os.path.join(work, "objects.json")
    peerlib.write_frame(frame)
    peerlib.write_objects(objects, OBJECTS)
    serve = peerlib.Serve(["--frame", frame, "--robot", "modbus-server://127.0.0.1:0",
                           "--replay", objects, "--cycles", str(2 * CYCLES)])
    crowd = None
    try:
        _, port = serve.host_port()
        steps = []

        def plc_run(first, last_run=False):
            start = time.time()
            plc = Plc(port, timeout=10.0)
            steps.append(("connect", time.time() - start))
            for i in range(CYCLES):
                start = time.time()
                status, poses = plc.cycle(first + i)
                steps.append(("cycle %d" % (first + i), time.time() - start))
                check(status == RESULT_READY, "request %d: status %d" % (first + i, status))
                check(len(poses) == 2 and all(abs(a - b) <= 0.011 for p, e in zip(poses, EXPECTED)
                                              for a, b in zip(p, e)),
                      "request %d: poses %s" % (first + i, poses))
            if not last_run:  # after the last cycle's acknowledge serve exits
                plc.wait_consumed()
            plc.close()

        alone = timed(lambda: plc_run(100))
        crowd = Crowd(port)
        crowd.add(garbage, 2, 2)
        crowd.add(send_then_hold(mbap(b"\x03\x00\x00\x00\x01", length=0xFFFF) + b"\x55" * 100), 2, 3)
        crowd.add(request_loop(mbap(b"\x5a\x00\x00\x00\x01")), 2, 4)
        crowd.add(request_loop(mbap(struct.pack(">BHH", 3, 0, 2000))), 2, 5)
        crowd.add(request_loop(mbap(struct.pack(">BHHBHH", 16, 60000, 2, 4, 1, 1))), 2, 6)
        crowd.add(hold_until_closed, 10, 2)
        crowd.add(trickle(READ_TWO), 2, 3)
        crowd.add(send_then_hold(READ_TWO[:9]), 2, 4)
        crowd.add(flood_without_reading(READ_TWO), 1, 5)
        crowd.start()
        time.sleep(1.0)
        hostile = timed(lambda: plc_run(200, last_run=True))
        connections = crowd.connections
        crowd.close()
        code = serve.wait(timeout=30)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)))
        print("modbus-server via serve: PLC %d cycles alone %.3f s, with 25 hostile clients "
              "%.3f s (%d hostile connections)" % (CYCLES, alone, hostile, connections))
        slowest = max(steps, key=lambda step: step[1])
        check(hostile <= 2 * alone + 1.0, "with hostile clients %.3f s > 2 x %.3f s + 1 s "
              "(slowest step: %s, %.3f s)" % (hostile, alone, slowest[0], slowest[1]))
    finally:
        if crowd is not None:
            crowd.close()
        serve.kill()


def vision_server():
    work = peerlib.scratch_dir("hostile-vision")
    frame, objects = os.path.join(work, "frame.yml"), os.path.join(work, "objects.json")
    peerlib.write_frame(frame)
    peerlib.write_objects(objects, OBJECTS)
    serve = peerlib.Serve(["--frame", frame, "--robot", "vision-server://127.0.0.1:0",
                           "--replay", objects, "--cycles", str(2 * CYCLES)])
    crowd = None
    try:
        host, port = serve.host_port()
        steps = []

        def robot_run():
            start = time.time()
            robot = URSocket(host, port, timeout=10.0)
            steps.append(("connect", time.time() - start))
            for i in range(CYCLES):
                start = time.time()
                robot.send_line("TRIG")
                reply = robot.read_ascii_float(7)
                check(reply[0] == 7 and reply[1] == 1, "cycle %d: reply %r" % (i, reply))
                x, y, z = EXPECTED[0][:3]
                check(abs(reply[2] - x / 1000) < 1e-6 and abs(reply[3] - y / 1000) < 1e-6 and
                      abs(reply[4] - z / 1000) < 1e-6, "cycle %d: pose %r" % (i, reply))
                steps.append(("cycle %d" % i, time.time() - start))
            robot.close()

        alone = timed(robot_run)
        crowd = Crowd(port)
        crowd.add(garbage, 2, 2)
        crowd.add(request_loop(b"A" * 300), 2, 3)
        crowd.add(request_loop(b"trig\n"), 2, 4)
        crowd.add(hold_until_closed, 10, 2)
        crowd.add(trickle(b"XXXXXXXX"), 2, 5)
        crowd.add(flood_without_reading(b"HELLO\n"), 1, 6)
        crowd.start()
        time.sleep(1.0)
        hostile = timed(robot_run)
        connections = crowd.connections
        crowd.close()
        code = serve.wait(timeout=30)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)))
        print("vision-server via serve: robot %d TRIG cycles alone %.3f s, with 19 hostile "
              "clients %.3f s (%d hostile connections)" % (CYCLES, alone, hostile, connections))
        slowest = max(steps, key=lambda step: step[1])
        check(hostile <= 2 * alone + 1.0, "with hostile clients %.3f s > 2 x %.3f s + 1 s "
              "(slowest step: %s, %.3f s)" % (hostile, alone, slowest[0], slowest[1]))
    finally:
        if crowd is not None:
            crowd.close()
        serve.kill()


if __name__ == "__main__":
    random.seed(15)
    modbus_server()
    vision_server()
