"""No function numba caches on disk calls a ``parallel=True`` one.

A cached compiled function that calls a cached threaded (``parallel=True``) function
can segfault when loaded from the cache, most reliably after several processes filled the
cache at once (github.com/numba/numba/issues/4807 and /8578). This crashed the sample preparation of the
default workflow in a fresh clone (its four samples are prepared by concurrent jobs), so
the threaded kernels are not cached and only Python calls them (linear.cg._pcg_threaded).
"""

import importlib
import pkgutil

from numba.core.registry import CPUDispatcher

import asphalt_nscd


def _dispatchers():
    for info in pkgutil.walk_packages(asphalt_nscd.__path__, "asphalt_nscd."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == module.__name__:
                yield f"{module.__name__}.{name}", obj


def _cached(d):
    return bool(d.targetoptions.get("cache")) or type(d._cache).__name__ != "NullCache"


def test_cached_functions_call_no_threaded_function():
    found = dict(_dispatchers())
    threaded = {n for n, d in found.items() if d.targetoptions.get("parallel")}
    assert "asphalt_nscd.nscd.linear.cg._matvec_par" in threaded  # the scan sees them
    offenders = []
    for name, d in found.items():
        if not _cached(d):
            continue
        assert not d.targetoptions.get("parallel"), f"{name} is threaded and cached"
        module = importlib.import_module(d.py_func.__module__)
        for g in d.py_func.__code__.co_names:
            callee = getattr(module, g, None)
            if isinstance(callee, CPUDispatcher) and callee.targetoptions.get("parallel"):
                offenders.append(f"{name} -> {g}")
    assert not offenders, offenders
