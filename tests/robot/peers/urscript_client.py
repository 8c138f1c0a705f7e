"""A robot-side client with URScript's socket semantics, for the vision-server peer tests.

URScript (UR manual, socket functions): socket_open(address, port) gives up after 2 s;
socket_send_string(s) sends s as is; socket_send_line(s) sends s and a newline;
socket_read_ascii_float(n) reads a message of the form "(f1, f2, ..., fn)" and returns
[n, f1, ..., fn], or [0, nan, ..., nan] when the read fails or 2 s pass. This class does the
same and is strict where a robot program would be fragile: exactly n numbers or a failure.
"""
import math
import socket
import struct
import time


class URSocket:
    def __init__(self, host, port, timeout=2.0):
        self.timeout = timeout
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buffer = b""
        self.closed_by_server = False

    def send_string(self, text):
        self.sock.sendall(text.encode("ascii"))

    def send_line(self, text):
        self.send_string(text + "\n")

    def _fill(self, deadline):
        """More bytes into the buffer; False on timeout or EOF."""
        left = deadline - time.time()
        if left <= 0:
            return False
        self.sock.settimeout(left)
        try:
            data = self.sock.recv(4096)
        except (socket.timeout, ConnectionError, OSError):
            return False
        if not data:
            self.closed_by_server = True
            return False
        self.buffer += data
        return True

    def read_ascii_float(self, n):
        """[n, f1..fn] or [0, nan * n] - socket_read_ascii_float(n)."""
        failure = [0] + [math.nan] * n
        deadline = time.time() + self.timeout
        while b")" not in self.buffer:
            if not self._fill(deadline):
                return failure
        end = self.buffer.index(b")")
        message = self.buffer[:end + 1]
        self.buffer = self.buffer[end + 1:]
        # The reply line ends with a newline: take it with the message.
        if self.buffer.startswith(b"\n"):
            self.buffer = self.buffer[1:]
        text = message.decode("ascii", "replace").strip()
        if not text.startswith("(") or not text.endswith(")"):
            return failure
        fields = text[1:-1].split(",")
        if len(fields) != n:
            return failure
        try:
            values = [float(f) for f in fields]
        except ValueError:
            return failure
        if not all(math.isfinite(v) for v in values):
            return failure
        return [n] + values

    def sees_eof(self, timeout=2.0):
        """True when the server closes the connection within timeout."""
        deadline = time.time() + timeout
        while not self.closed_by_server:
            if not self._fill(deadline):
                break
        return self.closed_by_server

    def close(self):
        self.sock.close()

    def reset(self):
        """Vanish with a TCP reset (a killed robot program)."""
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self.sock.close()


def expected_rotation_vector(yaw_deg):
    """Rz(yaw) * Rx(180 deg) is a half turn about (cos(yaw/2), sin(yaw/2), 0): its rotation
    vector is pi times that axis (or its negative - the same rotation)."""
    half = math.radians(yaw_deg) / 2.0
    return (math.pi * math.cos(half), math.pi * math.sin(half), 0.0)


def same_rotation_vector(got, want, tolerance=1e-4):
    """Equal, or both half turns about opposite axes."""
    if all(abs(g - w) < tolerance for g, w in zip(got, want)):
        return True
    norm = math.sqrt(sum(w * w for w in want))
    return abs(norm - math.pi) < 1e-6 and all(abs(g + w) < tolerance for g, w in zip(got, want))
