#!/usr/bin/python3
"""Loads kernel modules with finit_module(2), in the order given (no dependency resolution).
Used inside user-mode Linux, where the host's Debian has no kmod (insmod/modprobe).
Exits 1 naming the module and the errno on the first failure; EEXIST (already loaded) is fine."""
import ctypes
import errno
import os
import sys

SYS_FINIT_MODULE = 313  # x86_64

libc = ctypes.CDLL(None, use_errno=True)
for path in sys.argv[1:]:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as e:
        print(f'insmod.py: {path}: {e.strerror}', flush=True)
        sys.exit(1)
    rc = libc.syscall(SYS_FINIT_MODULE, fd, b'', 0)
    err = ctypes.get_errno()
    os.close(fd)
    if rc != 0 and err != errno.EEXIST:
        print(f'insmod.py: {path}: finit_module: {os.strerror(err)}', flush=True)
        sys.exit(1)
    print(f'insmod.py: loaded {os.path.basename(path)}', flush=True)
