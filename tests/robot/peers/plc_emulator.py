"""A PLC emulator for the Modbus TCP robot link (docs/robot_modbus.md), on pymodbus 3.0.0's
synchronous client. Imported by the test_modbus_*.py peers; also runnable on its own (it is the
PLC the fault test kills mid-cycle):

    python3 plc_emulator.py PORT REQUEST_SEQUENCE die-after-trigger|die-after-result

Register map (holding registers, 0-based): 0 command (1 trigger, 2 acknowledge, 99 stop),
1 request sequence, 10 heartbeat, 11 status (int16), 12 result sequence, 13 pose count,
20 + 8 i: pose i as x, y, z (0.01 mm) and yaw (0.001 degree), int32 each, high word first.
"""
import os
import signal
import sys
import time

from pymodbus.client import ModbusTcpClient

COMMAND, REQUEST_SEQUENCE, HEARTBEAT, STATUS, RESULT_SEQUENCE, POSE_COUNT = 0, 1, 10, 11, 12, 13
FIRST_POSE, WORDS_PER_POSE = 20, 8
TRIGGER, ACKNOWLEDGE, STOP = 1, 2, 99
IDLE, BUSY, RESULT_READY = 0, 1, 2


def int16(word):
    """The status register's int16 two's complement."""
    return word - 0x10000 if word & 0x8000 else word


def int32(high, low):
    """A signed 32-bit value from two words, high word first."""
    value = (high << 16) | low
    return value - 0x100000000 if value & 0x80000000 else value


def words_of_int32(value):
    """The two words (high first) of a signed 32-bit value (for the controller side)."""
    value &= 0xFFFFFFFF
    return [value >> 16, value & 0xFFFF]


def decode_poses(words):
    """[(x_mm, y_mm, z_mm, yaw_deg), ...] from the pose words."""
    poses = []
    for i in range(0, len(words), WORDS_PER_POSE):
        block = words[i:i + WORDS_PER_POSE]
        poses.append((int32(block[0], block[1]) / 100.0, int32(block[2], block[3]) / 100.0,
                      int32(block[4], block[5]) / 100.0, int32(block[6], block[7]) / 1000.0))
    return poses


class ModbusError(RuntimeError):
    pass


class Plc:
    """The PLC side of the handshake over one TCP connection."""

    def __init__(self, port, host="127.0.0.1", timeout=3.0, poll_s=0.001):
        self.client = ModbusTcpClient(host, port=port, timeout=timeout, retries=0)
        self.poll_s = poll_s
        if not self.client.connect():
            raise ModbusError("cannot connect to %s:%d" % (host, port))

    def close(self):
        self.client.close()

    def read(self, address, count=1):
        response = self.client.read_holding_registers(address, count, slave=1)
        if response.isError():
            raise ModbusError("read %d+%d: %s" % (address, count, response))
        return list(response.registers)

    def write(self, address, values):
        if isinstance(values, int):
            response = self.client.write_register(address, values, slave=1)
        else:
            response = self.client.write_registers(address, list(values), slave=1)
        if response.isError():
            raise ModbusError("write %d: %s" % (address, response))

    def trigger(self, request_sequence):
        """Request sequence first, then the trigger command (two writes, as a PLC does)."""
        self.write(REQUEST_SEQUENCE, request_sequence & 0xFFFF)
        self.write(COMMAND, TRIGGER)

    def wait_result(self, request_sequence, timeout=10.0):
        """Polls until the status is final (2 or negative) for this request sequence.
        Returns (status, poses)."""
        deadline = time.time() + timeout
        while True:
            status, result_sequence, count = self.read(STATUS, 3)
            status = int16(status)
            if result_sequence == request_sequence & 0xFFFF and (status == RESULT_READY or
                                                                  status < 0):
                words = self.read(FIRST_POSE, count * WORDS_PER_POSE) if count else []
                return status, decode_poses(words)
            if time.time() > deadline:
                raise ModbusError("no result for request %d within %.1f s (status %d, result "
                                  "sequence %d)" % (request_sequence, timeout, status,
                                                    result_sequence))
            time.sleep(self.poll_s)

    def acknowledge(self):
        self.write(COMMAND, ACKNOWLEDGE)

    def wait_consumed(self, timeout=10.0):
        """Until the link has consumed the last command (register 0 reads 0)."""
        deadline = time.time() + timeout
        while self.read(COMMAND)[0] != 0:
            if time.time() > deadline:
                raise ModbusError("command not consumed within %.1f s" % timeout)
            time.sleep(self.poll_s)

    def cycle(self, request_sequence, timeout=10.0):
        """trigger -> poll status -> read poses -> acknowledge. Returns (status, poses)."""
        self.trigger(request_sequence)
        status, poses = self.wait_result(request_sequence, timeout)
        self.acknowledge()
        return status, poses

    def stop(self):
        self.write(COMMAND, STOP)


def main():
    port, request_sequence, mode = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    plc = Plc(port)
    plc.trigger(request_sequence)
    if mode == "die-after-result":
        status, poses = plc.wait_result(request_sequence)
        print("result %d %d" % (status, len(poses)), flush=True)
    elif mode != "die-after-trigger":
        raise SystemExit("unknown mode " + mode)
    os.kill(os.getpid(), signal.SIGKILL)  # no acknowledge, no orderly close


if __name__ == "__main__":
    main()
