#!/usr/bin/env python3
"""The probe's CAN frames against an independent peer: python-can (Debian's python3-can).

Both directions, with the protocol packed here from probe.dbc's documentation alone (struct and
bit arithmetic, a bit-by-bit CRC-8/SAE-J1850), sharing no code with the C++ codec:

1. python-can writes a candump log (CanutilsLogWriter) of a probe stream made here: 200 Hz
   orientations with two frames dropped, one frame corrupted in transit, 10 Hz status and an
   input frame. ultrasim-probe-bringup replays it; every decoded value, the rate, the missed
   frames and the refused frame must be what was sent.
2. ultrasim-probe-bringup writes its demo log (our encoder, our log writer); python-can reads it
   (CanutilsLogReader) and the frames are decoded here: the orientation must turn about z at
   30 degrees a second, every checksum must hold.

Usage: probe_can_peer_test.py PATH/TO/ultrasim-probe-bringup
"""

import json
import math
import os
import subprocess
import sys
import tempfile

import can

ORIENTATION, STATUS, INPUT = 0x101, 0x100, 0x102
SCALE = math.sqrt(0.5) / 16383  # QuatA..C: 15-bit signed over +-1/sqrt(2)


def crc8_sae_j1850(data):
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def with_checksum(can_id, first7):
    first7 = bytes(first7)
    return first7 + bytes([crc8_sae_j1850(bytes([can_id & 0xFF, can_id >> 8]) + first7)])


def orientation_frame(w, x, y, z, sequence):
    q = [w, x, y, z]
    largest = max(range(4), key=lambda i: abs(q[i]))
    sign = -1.0 if q[largest] < 0 else 1.0
    rest = [sign * q[i] for i in range(4) if i != largest]
    bits = 0
    for k, value in enumerate(rest):
        bits |= (round(value / SCALE) & 0x7FFF) << (15 * k)
    bits |= largest << 45
    bits |= sequence << 48
    return with_checksum(ORIENTATION, bits.to_bytes(8, "little")[:7])


def decode_orientation(data):
    bits = int.from_bytes(data, "little")
    rest = []
    for k in range(3):
        raw = (bits >> (15 * k)) & 0x7FFF
        rest.append((raw - 0x8000 if raw & 0x4000 else raw) * SCALE)
    largest = (bits >> 45) & 3
    left_out = math.sqrt(max(0.0, 1.0 - sum(v * v for v in rest)))
    q = rest[:largest] + [left_out] + rest[largest:]
    return q, (bits >> 48) & 0xFF


def status_frame(sequence):
    # firmware 3.1, calibration 3/3/2/1, error flags 0x0004, 200 Hz (raw 50)
    cal = 3 | 3 << 2 | 2 << 4 | 1 << 6
    return with_checksum(STATUS, [3, 1, cal, 0x04, 0x00, 50, sequence])


def input_frame(sequence):
    force = round(7.25 / 0.01)  # 7.25 N
    return with_checksum(INPUT, [0b000110, 0, force & 0xFF, force >> 8, 0, 0, sequence])


def check(condition, message):
    if not condition:
        print("FAIL:", message)
        sys.exit(1)


def python_writes_we_read(tool, folder):
    log = os.path.join(folder, "from-python.log")
    writer = can.CanutilsLogWriter(log, channel="can0")
    sent = {}
    t0 = 1_700_000_000.0
    dropped = {37, 38}
    corrupted = 90
    for i in range(200):
        angle = math.radians(0.5 * i)  # about the y axis, then tilted
        q = (math.cos(angle / 2), 0.1 * math.sin(angle / 2), math.sin(angle / 2), 0.0)
        norm = math.sqrt(sum(c * c for c in q))
        q = tuple(c / norm for c in q)
        if i in dropped:
            continue
        data = bytearray(orientation_frame(*q, sequence=i % 256))
        if i == corrupted:
            data[1] ^= 0x01  # a bit flipped on the wire: the checksum must catch it
        else:
            sent[i] = q
        writer.on_message_received(
            can.Message(timestamp=t0 + i * 0.005, arbitration_id=ORIENTATION,
                        is_extended_id=False, data=bytes(data)))
        if i % 20 == 0:
            writer.on_message_received(
                can.Message(timestamp=t0 + i * 0.005 + 0.0001, arbitration_id=STATUS,
                            is_extended_id=False, data=status_frame(i // 20)))
    writer.on_message_received(
        can.Message(timestamp=t0 + 1.0, arbitration_id=INPUT, is_extended_id=False,
                    data=input_frame(5)))
    writer.stop()

    out = subprocess.run([tool, "--replay", log, "--frames"], capture_output=True, text=True,
                         check=False)
    check(out.returncode == 0, f"bring-up tool failed: {out.stderr}")
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    summary = lines[-1]["traffic"]
    driver = lines[-1]["driver"]
    frames = lines[:-1]
    orientations = [f for f in frames if f.get("message") == "ProbeOrientation"]
    check(len(orientations) == len(sent), f"{len(orientations)} orientations, sent {len(sent)}")
    worst = 0.0
    for f in orientations:
        want = sent[f["sequence"]] if f["sequence"] in sent else None
        check(want is not None, f"sequence {f['sequence']} was not sent intact")
        got = (f["w"], f["x"], f["y"], f["z"])
        dot = abs(sum(a * b for a, b in zip(got, want)))
        worst = max(worst, 2 * math.acos(min(1.0, dot)))
    check(math.degrees(worst) < 0.01, f"orientation error {math.degrees(worst):.4f} deg")
    status = [f for f in frames if f.get("message") == "ProbeStatus"]
    check(len(status) == 10, f"{len(status)} status frames")
    check(status[0]["firmware"] == "3.1" and status[0]["calibration"] == [3, 3, 2, 1]
          and status[0]["error_flags"] == 4 and status[0]["orientation_rate_hz"] == 200,
          f"status decoded as {status[0]}")
    inputs = [f for f in frames if f.get("message") == "ProbeInput"]
    check(len(inputs) == 1 and inputs[0]["buttons"] == [0, 1, 1, 0, 0, 0]
          and abs(inputs[0]["compression_force_n"] - 7.25) < 1e-9, f"input decoded as {inputs}")
    errors = [f for f in frames if "error" in f]
    check(len(errors) == 1 and errors[0]["error"] == "checksum mismatch", f"errors: {errors}")
    o = summary["messages"]["ProbeOrientation"]
    # Dropped 37 and 38 are two missed; the corrupted 90 never reached the tracker, so 91
    # follows 89: one more.
    check(o["missed"] == 3, f"missed {o['missed']}, expected 3")
    check(o["interval_us"]["p50"] == 5000, f"interval p50 {o['interval_us']['p50']}")
    # 197 frames arrived, the first at 0 s and the last at 0.995 s.
    check(abs(o["rate_hz"] - 196 / 0.995) < 0.01, f"rate {o['rate_hz']}")
    check(summary["errors"]["checksum mismatch"] == 1, "checksum errors in the summary")
    # The driver saw the same stream: its status said 200 Hz, as asked, so it streams; its
    # arrival intervals are the 5 ms of the log (the dropped and corrupted ones aside).
    check(driver["state"] == "streaming", f"driver state {driver['state']}")
    check(driver["counters"]["missed"] == 3, f"driver missed {driver['counters']['missed']}")
    check(driver["orientation_interval_us"]["p50"] == 5100,
          f"driver interval p50 {driver['orientation_interval_us']['p50']}")
    print(f"python-can -> ultrasim: {len(orientations)} orientations within "
          f"{math.degrees(worst):.4f} deg, 3 missed, 1 corrupted frame refused")


def we_write_python_reads(tool, folder):
    log = os.path.join(folder, "from-ultrasim.log")
    out = subprocess.run([tool, "--write-demo", log, "--seconds", "0.5"], capture_output=True,
                         text=True, check=False)
    check(out.returncode == 0, f"--write-demo failed: {out.stderr}")
    messages = list(can.CanutilsLogReader(log))
    orientations = [m for m in messages if m.arbitration_id == ORIENTATION]
    check(len(orientations) == 100, f"{len(orientations)} orientation frames in 0.5 s")
    t0 = orientations[0].timestamp
    worst = 0.0
    for m in messages:
        data = bytes(m.data)
        check(len(data) == 8 and not m.is_extended_id, f"frame {m}")
        check(data[7] == crc8_sae_j1850(bytes([m.arbitration_id & 0xFF, m.arbitration_id >> 8])
                                        + data[:7]), f"checksum of {m}")
    for k, m in enumerate(orientations):
        q, sequence = decode_orientation(bytes(m.data))
        check(sequence == k % 256, f"sequence {sequence} at frame {k}")
        angle = math.radians(30.0) * (m.timestamp - t0)
        want = (math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2))
        dot = abs(sum(a * b for a, b in zip(q, want)))
        worst = max(worst, 2 * math.acos(min(1.0, dot)))
    check(math.degrees(worst) < 0.01, f"demo orientation error {math.degrees(worst):.4f} deg")
    # Boresight on the same log: the mount must undo the last orientation (q_last^-1), as
    # decoded here.
    out = subprocess.run([tool, "--replay", log, "--boresight"], capture_output=True, text=True,
                         check=False)
    check(out.returncode == 0, f"--boresight failed: {out.stderr}")
    mount = json.loads(out.stdout.splitlines()[-1])["mount_wxyz"]
    q_last, _ = decode_orientation(bytes(orientations[-1].data))
    # q_last x mount must be the identity: its vector part vanishes (angle = 2 atan(|v| / |w|)).
    w1, x1, y1, z1 = q_last
    w2, x2, y2, z2 = mount
    product = (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
               w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)
    angle = 2 * math.atan2(math.sqrt(sum(c * c for c in product[1:])), abs(product[0]))
    check(math.degrees(angle) < 0.01, f"boresight mount {mount}: {math.degrees(angle):.4f} deg")
    print(f"ultrasim -> python-can: {len(messages)} frames, orientation within "
          f"{math.degrees(worst):.4f} deg, every checksum holds")


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    with tempfile.TemporaryDirectory() as folder:
        python_writes_we_read(sys.argv[1], folder)
        we_write_python_reads(sys.argv[1], folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
