"""Keeps numba's cache of the package's compiled kernels true to their sources.

Numba stores a kernel compiled with ``cache=True`` beside its source (``__pycache__/*.nbi``
and ``*.nbc``) and checks it against that one file's time stamp. A kernel that calls a kernel
from another file carries the callee compiled into it, so editing the callee (say the
particle update's tempering, which the bridge's and the window's kernels call) leaves the
caller's cache stale: the caller goes on running the old code without a word. So the package
stamps its kernel files together: at import, when any file that compiles a kernel differs
from the stamp, every cached kernel of the package is dropped and compiled again on first use.

An installed package whose folder is not writable is left alone: its files do not change in
place, and numba then keeps its cache in the user's cache folder, keyed on the files' stamps.
"""

import hashlib
import os
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
#: The stamp's file, in the package's own ``__pycache__``.
STAMP = "kernel_sources.sha1"
_CACHE_SUFFIXES = (".nbi", ".nbc")


def kernel_digest(package: Path = PACKAGE) -> str:
    """SHA-1 over the path and bytes of every module of ``package`` that uses numba."""
    digest = hashlib.sha1()
    for path in sorted(package.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.relative_to(package).as_posix().encode())
            digest.update(text)
    return digest.hexdigest()


def refresh_kernel_cache(package: Path = PACKAGE) -> bool:
    """Drops ``package``'s cached kernels when its kernel files differ from the stamp, and
    stamps them; returns whether it dropped them. Does nothing where it cannot write."""
    stamp = package / "__pycache__" / STAMP
    if not os.access(package, os.W_OK):
        return False
    digest = kernel_digest(package)
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass  # no stamp yet: whatever is cached predates it
    for path in package.rglob("__pycache__/*"):
        if path.suffix in _CACHE_SUFFIXES:
            path.unlink(missing_ok=True)  # another process may have dropped it first
    stamp.parent.mkdir(exist_ok=True)
    partial = stamp.with_suffix(f".{os.getpid()}")
    partial.write_text(digest)
    os.replace(partial, stamp)  # atomic: a process reading it sees one stamp or the other
    return True
