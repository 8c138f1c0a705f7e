"""Forward kinematics of the thesis arm from its joint pulses, written independently of the C++
(from THESIS.md section 5 and robot::moveto in the thesis listing), for the serial peer tests.

Pulses a0..a4 of `PS 1,a0,a1,a2,a3,a4,a5`:
  waist     theta1 = -a0 / 40                       (deg)
  shoulder  sigma  = a1 / 40 + 35                   (upper-arm elevation)
  elbow     eps    = (1800 - a2) / 40               (bend; forearm elevation = sigma - eps)
  wrist     a3 = 1200 - 40/3 (theta4 + theta5), a4 = 1200 + 40/3 (theta4 - theta5)
            theta4 = A - 90 + forearm elevation + 1.9, theta5 = S - theta1
Lengths (mm): shoulder height 250, upper arm 220, forearm 160, tool 214.6.
"""
import math

SHOULDER_HEIGHT = 250.0
UPPER_ARM = 220.0
FOREARM = 160.0
TOOL = 214.6


def forward(pulses):
    """(x, y, z) mm of the grip point, tool pitch A (deg, 180 = down), roll S (deg)."""
    a0, a1, a2, a3, a4 = pulses[:5]
    k, kw = 40.0, 40.0 / 3.0
    theta1 = -a0 / k
    sigma = a1 / k + 35.0
    eps = (1800.0 - a2) / k
    forearm = sigma - eps
    theta4 = (a4 - a3) / (2 * kw)
    theta5 = (2400.0 - a3 - a4) / (2 * kw)
    pitch = theta4 - 1.9 + 90.0 - forearm
    rho = (UPPER_ARM * math.cos(math.radians(sigma)) + FOREARM * math.cos(math.radians(forearm))
           + TOOL * math.sin(math.radians(pitch)))
    z = (SHOULDER_HEIGHT + UPPER_ARM * math.sin(math.radians(sigma))
         + FOREARM * math.sin(math.radians(forearm)) + TOOL * math.cos(math.radians(pitch)))
    return ((rho * math.cos(math.radians(theta1)), rho * math.sin(math.radians(theta1)), z),
            pitch, theta5 + theta1)


def parse_ps(line):
    """`PS 1,a0,...,a5` -> [a0..a5]; raises ValueError otherwise."""
    if not line.startswith("PS 1,"):
        raise ValueError("not a PS line: %r" % line)
    values = [int(v) for v in line[len("PS 1,"):].split(",")]
    if len(values) != 6:
        raise ValueError("PS needs 6 numbers: %r" % line)
    return values


def roll_difference(a, b):
    """|a - b| modulo 180 deg (parallel jaws grip the same at a and a + 180)."""
    d = math.fmod(a - b, 180.0)
    if d > 90:
        d -= 180
    if d < -90:
        d += 180
    return abs(d)
