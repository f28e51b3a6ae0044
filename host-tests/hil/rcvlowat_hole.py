#!/usr/bin/env python3
"""Shows whether this kernel leaves a blocking TCP read under SO_RCVLOWAT asleep with the rest
of its request queued (why `cargo xtask hil`'s bridge waits in poll: xtask/src/frame_socket.rs).

A reader blocks in recv(16) under a low-water mark of 16. Five bytes arrive; the reader is then
woken early (here by lowering the mark to 1 and raising it again, which makes the kernel re-check
it) and copies them. Eleven more bytes arrive: the reader now needs exactly those, but the
kernel compares the bytes it has not copied (11) with the mark (16) and does not wake it.

Prints what happened; exits 0 either way (it reports on the kernel, it is not a test).
Usage: python3 host-tests/hil/rcvlowat_hole.py
"""
import fcntl
import platform
import socket
import struct
import termios
import threading
import time

listener = socket.socket()
listener.bind(("127.0.0.1", 0))
listener.listen(1)
writer = socket.create_connection(listener.getsockname())
writer.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
reader, _ = listener.accept()
reader.setsockopt(socket.SOL_SOCKET, socket.SO_RCVLOWAT, 16)

got = {}


def read():
    started = time.time()
    data = reader.recv(16)
    got["bytes"], got["after_s"] = len(data), time.time() - started


thread = threading.Thread(target=read, daemon=True)
thread.start()
time.sleep(0.2)
for _ in range(5):  # one segment each, as QEMU's UART sends them
    writer.send(b"a")
    time.sleep(0.01)
time.sleep(0.2)
reader.setsockopt(socket.SOL_SOCKET, socket.SO_RCVLOWAT, 1)  # an early wake-up
reader.setsockopt(socket.SOL_SOCKET, socket.SO_RCVLOWAT, 16)
time.sleep(0.2)
for _ in range(11):
    writer.send(b"b")
    time.sleep(0.01)
thread.join(timeout=3.0)
unread = struct.unpack("i", fcntl.ioctl(reader, termios.FIONREAD, b"\0\0\0\0"))[0]
kernel = platform.release()
if thread.is_alive():
    print(f"Linux {kernel}: the hole is there: recv(16) still asleep after 3 s, "
          f"with {unread} bytes queued and unread")
else:
    print(f"Linux {kernel}: no hole: recv returned {got['bytes']} bytes after "
          f"{got['after_s']:.2f} s ({unread} bytes left queued)")
