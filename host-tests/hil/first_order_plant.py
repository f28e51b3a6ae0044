#!/usr/bin/env python3
"""A plant program for the virtual bench written from docs/hil.md alone (no project code).

The "actuator" is deliberately not the project's model: no hysteresis, an anhysteretic
magnetization M/M_s = tanh(c0 * i / h_sat) and quadratic magnetostriction
y_static = offset + stroke * (M/M_s)**2 behind a first-order lag, integrated with explicit Euler at 20
sub-steps per control period. It reads the firmware's 16-byte command frames on stdin and
answers with 8-byte sample frames (ADC counts scaled with the parameter file's `sensor`
section) on stdout. Used by `cargo xtask hil --check` to prove that any program speaking the
protocol can stand in for the default plant.
"""
import argparse
import os
import json
import math
import struct
import sys

SYNC = 0xA5


def read_exact(stream, n):
    data = b""
    while len(data) < n:
        chunk = stream.read(n - len(data))
        if not chunk:
            return None if not data else sys.exit(f"link closed inside a frame ({len(data)} bytes)")
        data += chunk
    return data


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--params", required=True, help="parameter file (for the sensor section)")
    ap.add_argument("--stroke-m", type=float, default=67e-6, help="displacement at saturation")
    ap.add_argument("--mount-offset-m", type=float, default=2e-6,
                    help="the sensor's reading with the rod at rest and unmagnetized")
    ap.add_argument("--h-sat-a-per-m", type=float, default=12e3, help="field scale of the tanh")
    ap.add_argument("--tau-s", type=float, default=2e-4, help="lag time constant")
    args = ap.parse_args()
    with open(args.params) as f:
        p = json.load(f)
    sensor = p["sensor"]
    gain = sensor["gain_m_per_count"]
    offset = sensor["offset_m"]
    max_count = (1 << sensor["adc_bits"]) - 1
    c0 = p["actuator"]["coil_factor_per_m"]

    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    begin = read_exact(stdin, 16)
    if begin is None:
        sys.exit("no B frame")
    sync, kind, seq, rate_hz, ticks, flags, _res, aux = struct.unpack("<BBHfIBBH", begin)
    if sync != SYNC or kind != ord("B"):
        sys.exit(f"expected a B frame, got {begin!r}")
    dt = 1.0 / rate_hz / 20
    y = args.mount_offset_m

    def send(tick, y_m):
        count = round((y_m - offset) / gain)
        count = min(max(count, 0), max_count)
        stdout.write(struct.pack("<BBHI", SYNC, ord("S"), tick & 0xFFFF, count))
        stdout.flush()

    # Optional (docs/hil.md, "Scoring"): the true displacement at the end of each tick's period,
    # so that the bench scores the tracking on it rather than on the sensed value.
    true_path = os.environ.get("HIL_TRUE_DISPLACEMENT_CSV")
    true_log = open(true_path, "w") if true_path else None
    if true_log:
        true_log.write("tick,y_m\n")

    send(0, y)
    tick = 0
    while True:
        frame = read_exact(stdin, 16)
        if frame is None:
            sys.exit(f"link closed at tick {tick} without an E frame")
        sync, kind, seq, current_a, desired_m, flags, _res, aux = struct.unpack("<BBHffBBH", frame)
        if sync != SYNC:
            sys.exit(f"bad sync byte {sync:#x}")
        if kind == ord("E"):
            print(f"first_order_plant: E after {tick} ticks, firmware status {aux}", file=sys.stderr)
            return
        if kind != ord("C") or seq != tick & 0xFFFF:
            sys.exit(f"unexpected frame kind {kind} seq {seq} at tick {tick}")
        target = args.mount_offset_m + args.stroke_m * math.tanh(c0 * current_a / args.h_sat_a_per_m) ** 2
        for _ in range(20):
            y += dt / args.tau_s * (target - y)
        if true_log:
            true_log.write(f"{tick},{y!r}\n")
        tick += 1
        if tick < ticks:
            send(tick, y)


if __name__ == "__main__":
    main()
