"""The order in which ``make test`` hands the test modules to its workers (tests/conftest.py)."""

from __future__ import annotations


def slow_modules_first(items: list) -> list:
    """``items`` (collected tests) with the modules that hold a ``slow`` test first, the workflow runs
    (tests/workflow/) before the others, each module's tests in their order and the other modules after
    in theirs. Under ``make test``'s workers (``--dist loadscope --no-loadscope-reorder``: whole modules
    handed out in this order) the longest modules, the smoke runs of the workflow, start at once instead
    of last."""
    slow = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}

    def rank(item) -> int:
        module = item.nodeid.split("::")[0]
        if module not in slow:
            return 2
        return 0 if module.startswith("tests/workflow/") else 1

    return sorted(items, key=rank)
