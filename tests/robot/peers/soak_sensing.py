"""Soak with real sensing (opt-in: HNNSTEREO_SOAK=1, else it exits 77 = skipped in CTest).

`hnnstereo serve` senses a rendered scene (seed 100, its own calib.yml, no --replay) on every
trigger of a PLC emulator over `modbus-server://`, for HNNSTEREO_SOAK_CYCLES cycles (1,000; then
the PLC's stop command ends serve). The
PLC runs in a child process that is killed with SIGKILL (no acknowledge pending, no orderly
close) and started again every 100 cycles, as a PLC that is power-cycled. Checked:
- none lost or duplicated: every request sequence gets exactly one result, with every part of the
  scene, and serve's report counts exactly the cycles the PLCs asked for;
- resident memory of serve grows < 5 % between cycle 100 and the last cycle;
- serve's open file descriptors do not grow between cycle 100 and the last cycle.
Prints the figures docs/robot.md quotes ("Soak with real sensing").

    HNNSTEREO_SOAK=1 ctest --test-dir build -R robot_soak_sensing --output-on-failure
    # or: HNNSTEREO_SOAK=1 HNNSTEREO_BINARY=build/hnnstereo python3 tests/robot/peers/soak_sensing.py
"""
import json
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peerlib  # noqa: E402
from peerlib import check  # noqa: E402
from plc_emulator import Plc  # noqa: E402

RESTART_EVERY = 100

# The PLC child: connects, runs cycles FIRST..LAST (request sequence = cycle number), prints one
# JSON line per result, then waits to be killed (it never closes the connection itself).
PLC_CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
from plc_emulator import Plc
port, first, last = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
deadline = time.time() + 10.0
while True:
    try:
        plc = Plc(port)
        break
    except Exception:
        if time.time() > deadline:
            raise
        time.sleep(0.05)
for request in range(first, last + 1):
    status, poses = plc.cycle(request % 65536, timeout=60.0)
    print(json.dumps({"request": request, "status": status, "poses": poses}), flush=True)
print("done", flush=True)
time.sleep(3600)
"""


def resident_kb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def open_fds(pid):
    return len(os.listdir("/proc/%d/fd" % pid))


def main():
    if os.environ.get("HNNSTEREO_SOAK") != "1":
        print("soak_sensing: skipped (set HNNSTEREO_SOAK=1 to run it)")
        sys.exit(77)
    cycles = int(os.environ.get("HNNSTEREO_SOAK_CYCLES", "1000"))
    check(cycles >= 2 * RESTART_EVERY, "HNNSTEREO_SOAK_CYCLES must be >= %d" % (2 * RESTART_EVERY))
    work = peerlib.scratch_dir("soak-sensing")
    scene = os.path.join(work, "scene")
    parts = len(peerlib.render_scene(100, scene))
    frame = os.path.join(work, "frame.yml")
    peerlib.write_frame(frame, workspace_min=(-1000, -1000, 0), workspace_max=(1500, 1500, 600))
    report = os.path.join(work, "report.json")
    serve = peerlib.Serve(["--left", os.path.join(scene, "left.png"),
                           "--right", os.path.join(scene, "right.png"),
                           "--calib", os.path.join(scene, "calib.yml"),
                           "--frame", frame, "--robot", "modbus-server://127.0.0.1:0",
                           "--max-reach", "3000", "--report", report], startup_timeout=60)
    here = os.path.dirname(os.path.abspath(__file__))
    seen = {}
    samples = {}
    start = time.time()
    try:
        _, port = serve.host_port()
        first = 1
        while first <= cycles:
            last = min(cycles, first + RESTART_EVERY - 1)
            plc = subprocess.Popen([sys.executable, "-c", PLC_CHILD, here, str(port), str(first),
                                    str(last)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True)
            for line in plc.stdout:
                if line.strip() == "done":
                    break
                result = json.loads(line)
                request = result["request"]
                check(request not in seen, "request %d answered twice" % request)
                seen[request] = result
                check(result["status"] == 2 and len(result["poses"]) == parts,
                      "cycle %d: status %d, %d poses for %d parts" %
                      (request, result["status"], len(result["poses"]), parts))
            else:
                plc.wait()
                check(False, "PLC child stopped early after request %d: %s" %
                      (max(seen) if seen else 0, plc.stderr.read()))
            if last == RESTART_EVERY or last == cycles:
                samples[last] = (resident_kb(serve.proc.pid), open_fds(serve.proc.pid))
            plc.send_signal(signal.SIGKILL)  # power-cycled: no orderly close
            plc.wait()
            plc.stdout.close()
            plc.stderr.close()
            first = last + 1
        elapsed = time.time() - start
        stopper = Plc(port)  # --cycles 0: serve runs until the PLC says stop
        stopper.stop()
        stopper.close()
        code = serve.wait(timeout=60)
        check(code == 0, "serve exit %d: %s" % (code, "".join(serve.stderr)[-2000:]))
        with open(report) as f:
            counters = json.load(f)
        link = counters["link"]
        check(sorted(seen) == list(range(1, cycles + 1)), "lost requests: %s" %
              sorted(set(range(1, cycles + 1)) - set(seen))[:20])
        check(counters["cycles"] == cycles and counters["sense_errors"] == 0 and
              counters["poses_published"] == parts * cycles, "report: %s" % counters)
        check(link["triggers"] == cycles and link["duplicate_triggers"] == 0 and
              link["cycles_published"] == cycles, "link: %s" % link)
        rss_100, fds_100 = samples[RESTART_EVERY]
        rss_end, fds_end = samples[cycles]
        growth = 100.0 * (rss_end - rss_100) / rss_100
        print("soak_sensing: %d cycles with real sensing (%d parts each) in %.1f s = %.0f ms a "
              "cycle, PLC killed and restarted %d times; none lost or duplicated" %
              (cycles, parts, elapsed, 1000.0 * elapsed / cycles, cycles // RESTART_EVERY - 1))
        print("soak_sensing: resident memory %d kB at cycle %d, %d kB at cycle %d (%+.2f %%); "
              "open descriptors %d -> %d" % (rss_100, RESTART_EVERY, rss_end, cycles, growth,
                                             fds_100, fds_end))
        check(growth < 5.0, "resident memory grew %.2f %% (limit 5 %%)" % growth)
        check(fds_end <= fds_100, "descriptors grew from %d to %d" % (fds_100, fds_end))
    finally:
        serve.kill()


if __name__ == "__main__":
    main()
