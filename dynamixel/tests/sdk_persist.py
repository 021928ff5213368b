#!/usr/bin/env python3
"""The bus settings across power cycles, with ROBOTIS' dynamixel-sdk, on one emulated board
served with a flash file (`vsa serve-qemu --bus PATH --ids 1 --qemu-flash F`). The xtask
(`cargo xtask dynamixel`) runs one STEP per boot, restarting the board with the same flash
file in between, and runs `vsa --port PATH bus ...` where a step says so:

    sdk_persist.py PATH STEP [--latency-ms N] [--baud BD]

  fresh     1.0: ping 1 (model 12); WRITE ID (3) = 5; ping 5; ID 1 silent; Lock (47) = 1;
            EEPROM writes (ID, Return Delay Time) refused with the range bit; Lock = 0
            refused.                                   [power cycle]
  stored    1.0: ping 5 (the ID was stored); ID 1 silent; the Lock is gone: Return Delay
            Time = 100 accepted.      [then `vsa bus --protocol 2` switches to 2.0]
  switched  2.0: ping 5 (model 1060); Return Delay Time (9) reads 100; WRITE Protocol Type
            (13) = 1 from 2.0; 1.0 ping 5.
                                      [then `vsa bus --protocol 2 --id 6`; power cycle]
  vsa       2.0: ping 6 (model 1060), ID 5 silent: what `vsa bus` set was stored.

Prints one line per check and exits 1 if any failed.
"""

import sys
import time

import dynamixel_sdk.port_handler
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

import sdk_check  # its check() prints the line and counts the failures
from sdk_check import check

RANGE, REFUSED = 0x08, 0x08 | 0x10 | 0x40


def ping(port, version, dxl_id):
    model, res, err = PacketHandler(version).ping(port, dxl_id)
    return model if res == COMM_SUCCESS else None


def answering(port, version, dxl_id, seconds=5.0):
    """Pings until the device answers (a switch takes effect after its status)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        model = ping(port, version, dxl_id)
        if model is not None:
            return model
        time.sleep(0.05)
    return None


def fresh(port):
    ph = PacketHandler(1.0)
    check(ping(port, 1.0, 1) == 12, "fresh flash: 1.0 ping 1 answers model 12")
    res, err = ph.write1ByteTxRx(port, 1, 3, 5)
    check(res == COMM_SUCCESS and err & REFUSED == 0, f"1.0 WRITE ID = 5 (result {res}, error 0x{err:02x})")
    check(answering(port, 1.0, 5) == 12, "1.0 ping 5 after the write")
    check(ping(port, 1.0, 1) is None, "ID 1 silent")
    res, err = ph.write1ByteTxRx(port, 5, 47, 1)
    check(res == COMM_SUCCESS and err & REFUSED == 0, f"1.0 Lock = 1 (error 0x{err:02x})")
    res, err = ph.write1ByteTxRx(port, 5, 3, 9)
    check(res == COMM_SUCCESS and err & RANGE, f"1.0 WRITE ID while locked: error 0x{err:02x} has range (0x08)")
    res, err = ph.write1ByteTxRx(port, 5, 5, 100)
    check(res == COMM_SUCCESS and err & RANGE, f"1.0 WRITE Return Delay Time while locked: error 0x{err:02x}")
    res, err = ph.write1ByteTxRx(port, 5, 47, 0)
    check(res == COMM_SUCCESS and err & RANGE, f"1.0 Lock = 0 while locked: error 0x{err:02x}")
    delay, res, _ = ph.read1ByteTxRx(port, 5, 5)
    check(res == COMM_SUCCESS and delay == 250, f"Return Delay Time still {delay}")


def stored(port):
    ph = PacketHandler(1.0)
    check(answering(port, 1.0, 5) == 12, "after the power cycle: 1.0 ping 5 (the ID was stored)")
    check(ping(port, 1.0, 1) is None, "ID 1 silent")
    lock, res, _ = ph.read1ByteTxRx(port, 5, 47)
    check(res == COMM_SUCCESS and lock == 0, f"Lock {lock} after the power cycle")
    res, err = ph.write1ByteTxRx(port, 5, 5, 100)
    check(res == COMM_SUCCESS and err & REFUSED == 0, f"1.0 WRITE Return Delay Time = 100 unlocked (error 0x{err:02x})")


def switched(port):
    ph = PacketHandler(2.0)
    check(answering(port, 2.0, 5) == 1060, "after `vsa bus --protocol 2`: 2.0 ping 5 answers model 1060")
    delay, res, err = ph.read1ByteTxRx(port, 5, 9)
    check(res == COMM_SUCCESS and delay == 100, f"2.0 Return Delay Time {delay} (100 written in 1.0)")
    res, err = ph.write1ByteTxRx(port, 5, 13, 1)
    check(res == COMM_SUCCESS and err == 0, f"2.0 WRITE Protocol Type = 1 (result {res}, error {err})")
    check(answering(port, 1.0, 5) == 12, "1.0 ping 5 after the switch from 2.0")


def vsa(port):
    check(answering(port, 2.0, 6) == 1060, "after `vsa bus --protocol 2 --id 6` and a power cycle: 2.0 ping 6")
    check(ping(port, 2.0, 5) is None, "ID 5 silent")


def main():
    args = sys.argv[1:]
    opts = {"--latency-ms": None, "--baud": 9600}
    for name in list(opts):
        if name in args:
            i = args.index(name)
            opts[name] = int(args[i + 1])
            del args[i:i + 2]
    path, step = args
    if opts["--latency-ms"] is not None:
        dynamixel_sdk.port_handler.LATENCY_TIMER = float(opts["--latency-ms"])
    port = PortHandler(path)
    if not port.openPort() or not port.setBaudRate(opts["--baud"]):
        print(f"cannot open {path}")
        return 1
    {"fresh": fresh, "stored": stored, "switched": switched, "vsa": vsa}[step](port)
    port.closePort()
    return 0 if sdk_check.failures == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
