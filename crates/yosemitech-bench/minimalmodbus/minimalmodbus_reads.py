#!/usr/bin/env python3
"""minimalmodbus reading the float at 0x2800 back to back for N seconds; prints transactions/s."""
import sys, time, minimalmodbus
port, baud, secs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
inst = minimalmodbus.Instrument(port, 1)
inst.serial.baudrate = baud
inst.serial.timeout = 0.5
for _ in range(20):
    inst.read_registers(0x2800, 2)
n, t0 = 0, time.monotonic()
while time.monotonic() - t0 < secs:
    inst.read_registers(0x2800, 2)
    n += 1
print(n / (time.monotonic() - t0))
