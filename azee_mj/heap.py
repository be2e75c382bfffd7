"""Give the memory a realization has freed back to the system.

A long realization frees its key postures, solver records and blend state (tens of MB per
hour of score) before it measures, saves and checks the frames. Those were many small
blocks interleaved with objects that live on, so the C allocator keeps their pages, and the
later stages' buffers come on top of them: the process's peak is the sum. Trimming the heap
(glibc's ``malloc_trim``, which returns every wholly free page, not only the heap's top)
lets the later stages reuse that memory instead.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc


@functools.cache
def _trim():
    """glibc's ``malloc_trim``, or None where the C library has none (musl, macOS)."""
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or None).malloc_trim
    except (OSError, AttributeError):
        return None


def release() -> bool:
    """Collect garbage cycles and return wholly free heap pages to the system. Returns
    whether the heap could be trimmed (False: only the collection ran)."""
    gc.collect()
    trim = _trim()
    if trim is None:
        return False
    trim(0)
    return True
