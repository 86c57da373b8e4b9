"""Callgrind's client requests from Python, without a compiler: the few bytes of machine code
``valgrind/callgrind.h`` expands to, put in an executable page and called through ctypes.

Valgrind recognises a "special instruction preamble" (rotations of a register that add up to
a whole turn, then ``xchg %ebx,%ebx``: a no-op on a real CPU) and treats the request whose
arguments %eax/%rax points to. Outside valgrind the code does nothing and returns 0. So a
benchmark can zero, toggle and dump callgrind's counts at exact points of its own Python (the
start of a tick), on x86-64 and on i386, with the interpreter and numpy it is given.
"""

from __future__ import annotations

import ctypes
import mmap
import platform
import struct

# valgrind.h / callgrind.h
_RUNNING_ON_VALGRIND = 0x1001
_CT = (ord("C") << 24) | (ord("T") << 16)
DUMP_STATS, ZERO_STATS, TOGGLE_COLLECT, DUMP_STATS_AT = _CT, _CT + 1, _CT + 2, _CT + 3
START_INSTRUMENTATION, STOP_INSTRUMENTATION = _CT + 4, _CT + 5

# `long request(unsigned long args[6])`: the preamble of valgrind.h, default result 0.
_AMD64 = bytes.fromhex(
    "4889f8"  # mov %rdi,%rax          (the argument block)
    "31d2"  # xor %edx,%edx          (default result)
    "48c1c703" "48c1c70d" "48c1c73d" "48c1c733"  # rol $3,$13,$61,$51 %rdi
    "4887db"  # xchg %rbx,%rbx         (the request)
    "4889d0"  # mov %rdx,%rax
    "c3"
)
_I386 = bytes.fromhex(
    "57"  # push %edi (callee-saved in cdecl)
    "8b442408"  # mov 8(%esp),%eax
    "31d2"  # xor %edx,%edx
    "c1c703" "c1c70d" "c1c71d" "c1c713"  # rol $3,$13,$29,$19 %edi
    "87db"  # xchg %ebx,%ebx
    "89d0"  # mov %edx,%eax
    "5f"  # pop %edi
    "c3"
)


class Callgrind:
    """The requests a counting benchmark needs; each is a no-op when not under valgrind."""

    def __init__(self) -> None:
        bits = struct.calcsize("P") * 8
        machine = platform.machine()
        if machine in ("x86_64", "AMD64") and bits == 64:
            code = _AMD64
        elif machine in ("i386", "i486", "i586", "i686", "x86_64") and bits == 32:
            code = _I386
        else:
            raise RuntimeError(f"callgrind requests: no code for {machine} ({bits}-bit)")
        self._page = mmap.mmap(-1, mmap.PAGESIZE, prot=mmap.PROT_READ | mmap.PROT_WRITE
                               | mmap.PROT_EXEC)
        self._page.write(code)
        address = ctypes.addressof(ctypes.c_char.from_buffer(self._page))
        self._call = ctypes.CFUNCTYPE(ctypes.c_ulong, ctypes.c_void_p)(address)
        self._args = (ctypes.c_ulong * 6)()
        self._names: list[ctypes.Array[ctypes.c_char]] = []  # kept alive for DUMP_STATS_AT
        self.running = self._request(_RUNNING_ON_VALGRIND) > 0

    def _request(self, code: int, arg: int = 0) -> int:
        self._args[0], self._args[1] = code, arg
        return int(self._call(ctypes.addressof(self._args)))

    def zero(self) -> None:
        self._request(ZERO_STATS)

    def toggle(self) -> None:
        """Start or stop counting (in the calling thread's state: ``--collect-atstart=no``)."""
        self._request(TOGGLE_COLLECT)

    def start_instrumentation(self) -> None:
        """Simulate from here (``--instr-atstart=no`` runs start-up at near native speed)."""
        self._request(START_INSTRUMENTATION)

    def stop_instrumentation(self) -> None:
        self._request(STOP_INSTRUMENTATION)

    def dump(self, label: str) -> None:
        """Write the counts so far to a part of the output file, named ``label``, and zero."""
        name = ctypes.create_string_buffer(label.encode())
        self._names.append(name)
        self._request(DUMP_STATS_AT, ctypes.addressof(name))
