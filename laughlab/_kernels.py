"""The same bytes on any x86-64 machine with AVX2: numpy's and OpenBLAS's CPU kernels pinned.

numpy 2 picks its ufunc loops by CPU when it is imported (AVX2 on most machines, AVX-512 where the
CPU has it), and OpenBLAS (numpy's and scipy's) its BLAS kernels (Haswell, SkylakeX, Zen...).  Their
float results differ in the last bits, and some computations amplify that: the Hill torso's
integration turned one such difference into 0.17 degrees of the BVH within seconds (measured
2026-11-26: ``tests/golden.py``'s ``hill_facs`` run on an AVX-512 machine against bytes recorded on
an AVX2 one; with the kernels pinned the two agree byte for byte, as do ``follow_detector`` and the
other runs without YAMNet).

So before numpy is first imported, laughlab asks both for their AVX2 kernels (x86-64-v3), on Linux
when the CPU has AVX2 and FMA: ``NPY_DISABLE_CPU_FEATURES`` names numpy's AVX-512 targets and
``OPENBLAS_CORETYPE=Haswell``.  The cost is small at laughlab's sizes (vectors of a frame, matrices of
a few dozen rows).  A variable the user set is left alone, and ``LAUGHLAB_NATIVE_KERNELS=1`` keeps the
libraries' own choice.  Where numpy was imported before laughlab, nothing can be changed any more:
:func:`state` says so, and ``results.json`` records it.

YAMNet's interpreter (LiteRT with XNNPACK) picks its kernels by CPU too, and they have no such switch;
``docs/architecture.md`` (*Reproducibility*) says what that means for ``detector=yamnet``.
"""
from __future__ import annotations

import os
import platform
import sys

#: numpy's dispatch targets above x86-64-v3 (numpy 2.x names)
NUMPY_AVX512 = ("X86_V4", "AVX512_ICL", "AVX512_SPR")


def cpu_flags() -> frozenset[str]:
    """The CPU's feature flags as Linux lists them (empty elsewhere)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


#: the CPU flags (Linux's names) behind XNNPACK's x86 kernel families (YAMNet's interpreter), in the order of
#: :func:`cpu_family`
FAMILIES = (("avx", {"avx"}), ("avx2", {"avx2", "fma"}), ("avx512f", {"avx512f"}),
            ("avx512skx", {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"}),
            ("avx512vbmi", {"avx512vbmi"}), ("avx512vnni", {"avx512_vnni"}), ("avxvnni", {"avx_vnni"}),
            ("amx", {"amx_int8"}))


def cpu_family() -> str:
    """The CPU's kernel families as XNNPACK tells them apart, e.g. ``avx+avx2`` or ``avx+avx2+avx512f+...``
    (the architecture's name outside x86-64 Linux): the default detector's bytes hold within one family."""
    import platform

    flags = cpu_flags()
    names = [name for name, need in FAMILIES if need <= flags]
    return "+".join(names) if names else platform.machine()


def pin() -> None:
    """Set the two variables (see the module notes) unless numpy is already imported, the user set them,
    or ``LAUGHLAB_NATIVE_KERNELS=1``."""
    if "numpy" in sys.modules or os.environ.get("LAUGHLAB_NATIVE_KERNELS") == "1":
        return
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return
    flags = cpu_flags()
    if not {"avx2", "fma"} <= flags:
        return
    if "avx512f" in flags:
        os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", ",".join(NUMPY_AVX512))
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")


def state() -> str:
    """What the kernels are: ``x86-64-v3 (pinned)``, ``native (...)`` and why, for ``results.json``."""
    if os.environ.get("LAUGHLAB_NATIVE_KERNELS") == "1":
        return "native (LAUGHLAB_NATIVE_KERNELS=1)"
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return f"native ({platform.machine()})"
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # another numpy than the lock's
        return "native (numpy's CPU features unknown)"
    if any(features.get(f) for f in NUMPY_AVX512):
        own = os.environ.get("NPY_DISABLE_CPU_FEATURES")
        if own is not None and not set(NUMPY_AVX512) <= set(own.replace(",", " ").split()):
            # the user's own value, kept by pin(): it was not numpy's import order (a reproducibility review)
            return f"native (NPY_DISABLE_CPU_FEATURES={own} leaves numpy's AVX-512 loops on)"
        return "native (numpy was imported before laughlab, with its AVX-512 loops)"
    if os.environ.get("OPENBLAS_CORETYPE", "").lower() != "haswell" and {"avx2", "fma"} <= cpu_flags():
        return "native (OpenBLAS chooses its kernels)"
    return "x86-64-v3 (pinned)"


_SAID = False


def warn_if_unpinned() -> None:
    """Once a process, when a ``Session`` is made (a notebook's way in): numpy was imported before laughlab with its
    AVX-512 loops, so results differ from the command line's in the last bits, and a Hill torso's by more (a Python
    user's review: a notebook imports numpy first, and only ``results.json`` recorded it)."""
    global _SAID
    if _SAID or "numpy was imported before laughlab" not in state():
        return
    _SAID = True
    import warnings

    warnings.warn("numpy was imported before laughlab, with its AVX-512 loops: the outputs may differ from the "
                  "command line's in the last bits (body=hill's by more). For the command line's bytes, import "
                  "laughlab before numpy (the notebook's first cell), or start Python with "
                  f"NPY_DISABLE_CPU_FEATURES={','.join(NUMPY_AVX512)} OPENBLAS_CORETYPE=Haswell", stacklevel=3)
