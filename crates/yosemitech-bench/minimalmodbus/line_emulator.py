#!/usr/bin/env python3
"""An independent Modbus RTU slave on a pty that keeps a real line's timing.

Serves holding registers of one slave (function 3): a float at 0x2800 (2 regs, little-endian image).
A reply is written when the wire would have carried it: the request's bytes, the slave's
turnaround (t3.5), then the reply's bytes, at the given baud, 10 bits a character.
Prints the pty path on stdout, then serves until killed.
"""
import os, sys, time, struct, select, termios, tty

def crc16(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc

def main():
    baud = int(sys.argv[1])
    slave = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    char = 10.0 / baud
    t35 = 3.5 * char if baud <= 19200 else 0.00175
    master, peer = os.openpty()
    tty.setraw(master)
    print(os.ttyname(peer), flush=True)
    regs = {0x2800: 0, 0x2801: 0}
    value = struct.pack('<f', 7.0)  # little-endian image of 7.0
    regs[0x2800] = value[0] | value[1] << 8
    regs[0x2801] = value[2] | value[3] << 8
    buf = b''
    while True:
        r, _, _ = select.select([master], [], [], 1.0)
        if not r:
            buf = b''
            continue
        try:
            chunk = os.read(master, 256)
        except OSError:
            time.sleep(0.01)
            continue
        arrived = time.monotonic()
        buf += chunk
        if len(buf) < 8:
            continue
        req, buf = buf[:8], buf[8:]
        if crc16(req[:6]) != struct.unpack('<H', req[6:])[0] or req[0] != slave or req[1] != 3:
            buf = b''
            continue
        start, count = struct.unpack('>HH', req[2:6])
        data = b''
        try:
            for a in range(start, start + count):
                data += struct.pack('>H', regs[a])
        except KeyError:
            continue  # silence for registers it lacks, like a real probe
        reply = bytes([slave, 3, len(data)]) + data
        reply += struct.pack('<H', crc16(reply))
        # The request took 8 characters on the wire; the pty delivered it at once.
        due = arrived + len(req) * char + t35 + len(reply) * char
        while True:
            left = due - time.monotonic()
            if left <= 0:
                break
            time.sleep(left if left > 0.0003 else 0)
        os.write(master, reply)

main()
