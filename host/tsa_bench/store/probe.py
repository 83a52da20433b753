"""Untrusted HDF5 files read first in a bounded child process.

Why: a damaged HDF5 file (a few flipped bytes in a global heap, say) can make the HDF5
library itself loop forever or allocate without bound inside one attribute read; no
Python-level check can interrupt a C loop. So before a command opens a file it did not
write, :func:`check_hdf5_terminates` forks a child that reads the file's structure (every
attribute, every dataset's type and shape and its whole chunk index, the scalar texts, the
text and table datasets in full up to :data:`WHOLE_ROWS` rows, the first and last row of
every other dataset: metadata and bounded slices only, never a long column's data), under
a memory limit and a CPU-time limit (:data:`CPU_LIMIT_S`: the library looping on a damaged
heap is stopped after that much CPU, however busy the machine), and waits at most
``timeout_s`` of wall time (a child blocked without using CPU). The reads are deterministic:
if the child finishes, the parent's own reads of the same objects finish too; if it hangs,
runs out of memory or crashes, the file is refused with a message saying so, and nothing
else is touched. A verdict is remembered for the same file (device, inode, size, time of
change) for the life of the process, so a command that reads a file twice pays once.

Contract: returns None when the child finished (whatever it found: ordinary errors, like a
missing dataset, are left to the caller's reader and its messages); otherwise the reason,
one line. Without ``os.fork`` (Windows) it returns None at once.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

#: How long the child may take (s of wall time); reading a run file's metadata takes milliseconds.
TIMEOUT_S = 20.0
#: CPU time the child may use (s, whole seconds: RLIMIT_CPU); a healthy file takes well under 0.1 s.
CPU_LIMIT_S = 1
#: Address-space limit of the child (bytes): a damaged heap must not take the machine.
MEMORY_LIMIT_BYTES = 4 << 30
#: Objects visited at most (groups and datasets); a run file has a few dozen.
MAX_OBJECTS = 10_000
#: A text or table dataset (strings, compound rows) with at most this many rows is read whole
#: (its strings live in heaps a damaged file can make the library loop on); others only at their ends.
WHOLE_ROWS = 100_000

_EXIT_DONE, _EXIT_MEMORY = 0, 3
_verdicts: dict[tuple[int, int, int, int], str | None] = {}


def _read_everything_small(path: Path) -> None:
    import h5py

    with h5py.File(path, "r") as f:
        seen = [0]

        def attrs(obj: h5py.HLObject) -> None:
            for name in obj.attrs:
                obj.attrs[name]

        def visit(_name: str, obj: h5py.HLObject) -> None:
            seen[0] += 1
            if seen[0] > MAX_OBJECTS:
                raise StopIteration
            attrs(obj)
            if isinstance(obj, h5py.Dataset):
                if obj.shape is None:
                    return
                if obj.chunks is not None:
                    obj.id.get_num_chunks()   # walks the whole chunk index (a cycle would loop here)
                texts = obj.dtype.kind in "OSUV" or obj.dtype.names is not None
                if obj.ndim == 0 or (texts and obj.ndim == 1 and obj.shape[0] <= WHOLE_ROWS):
                    obj[()]
                elif obj.size:
                    first = (0,) * obj.ndim
                    last = tuple(int(n) - 1 for n in obj.shape)
                    obj[first], obj[last]

        attrs(f)
        try:
            f.visititems(visit)
        except StopIteration:
            pass


def limit_memory(limit_bytes: int = MEMORY_LIMIT_BYTES) -> None:
    """Cap this process's address space at ``limit_bytes`` (a child reading an untrusted file:
    a damaged file then costs a MemoryError, not the machine); a no-op where it cannot."""
    try:
        import resource

        _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = limit_bytes if hard == resource.RLIM_INFINITY else min(limit_bytes, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass
    limit_cpu(whole_second=False)


def limit_cpu(whole_second: bool = True) -> None:
    """Allow this process :data:`CPU_LIMIT_S` more seconds of CPU from now (RLIMIT_CPU counts a
    process's whole life, so a child kept for many files calls this before each one). The limit
    is in whole seconds: ``whole_second`` allows at least :data:`CPU_LIMIT_S` (else what is left
    of the current second plus the rest). A no-op where it cannot."""
    try:
        import math
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_CPU)
        total = sum(resource.getrusage(resource.RUSAGE_SELF)[:2])   # a forked child inherits the count
        used = math.ceil(total) if whole_second else int(total)
        cpu = used + CPU_LIMIT_S if hard == resource.RLIM_INFINITY else min(used + CPU_LIMIT_S, hard)
        resource.setrlimit(resource.RLIMIT_CPU, (cpu, hard))
    except (ImportError, ValueError, OSError):
        pass


def _child(path: Path) -> None:
    """In the forked child: read, then leave without running any parent cleanup."""
    code = _EXIT_DONE
    limit_memory()
    try:
        _read_everything_small(path)
    except MemoryError:
        code = _EXIT_MEMORY
    except BaseException:   # an ordinary error: the caller's reader reports it in its own words
        code = _EXIT_DONE
    os._exit(code)


def check_hdf5_terminates(path: str | Path, timeout_s: float | None = None) -> str | None:
    """None if reading ``path``'s metadata finishes; else why not (module contract).

    ``timeout_s`` defaults to :data:`TIMEOUT_S`.
    """
    if not hasattr(os, "fork"):
        return None
    p = Path(path)
    try:
        st = os.stat(p)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_ctime_ns)
    except OSError:
        key = None
    if key is not None and key in _verdicts:
        return _verdicts[key]
    verdict = _check(p, TIMEOUT_S if timeout_s is None else timeout_s)
    if key is not None:
        _verdicts[key] = verdict
    return verdict


def _check(p: Path, timeout_s: float) -> str | None:
    if threading.active_count() > 1:
        # another thread may hold h5py's or HDF5's lock at the fork and the child would wait
        # on it for ever: a fresh interpreter instead (slower: it imports h5py)
        return _in_new_interpreter(p, timeout_s)
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child leaves through os._exit
        _child(p)
    deadline = time.monotonic() + timeout_s
    delay = 0.001
    status = None
    try:
        while status is None:
            done, st = os.waitpid(pid, os.WNOHANG)
            if done:
                status = st
            elif time.monotonic() >= deadline:
                return (f"damaged HDF5 file: reading its metadata did not finish in {timeout_s:g} s "
                        "(the HDF5 library loops on it)")
            else:
                time.sleep(delay)
                delay = min(delay * 2, 0.05)
    finally:
        if status is None:   # timed out, or Ctrl-C while waiting: never leave the child looping
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        return _verdict(-os.WTERMSIG(status))
    return _verdict(os.WEXITSTATUS(status) if os.WIFEXITED(status) else _EXIT_DONE)


def _verdict(code: int) -> str | None:
    """The reason for a child's exit code (negative: killed by that signal)."""
    if code in (-signal.SIGXCPU, -signal.SIGKILL):   # SIGKILL: past the hard CPU limit
        return (f"damaged HDF5 file: reading its metadata did not finish within {CPU_LIMIT_S} s of CPU time "
                "(the HDF5 library loops on it)")
    if code < 0:
        return f"damaged HDF5 file: the HDF5 library crashed reading it (signal {-code})"
    if code == _EXIT_MEMORY:
        return (f"damaged HDF5 file: reading its metadata needed more than {MEMORY_LIMIT_BYTES >> 30} GiB "
                "(a corrupt size or heap)")
    return None


def _in_new_interpreter(path: Path, timeout_s: float) -> str | None:
    try:
        done = subprocess.run([sys.executable, "-m", "tsa_bench.store.probe", str(path)], timeout=timeout_s + 5,
                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return (f"damaged HDF5 file: reading its metadata did not finish in {timeout_s:g} s "
                "(the HDF5 library loops on it)")
    except OSError:
        return None
    return _verdict(done.returncode)


if __name__ == "__main__":
    _child(Path(sys.argv[1]))
