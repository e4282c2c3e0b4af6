"""The product stands alone: no user-facing file points outside the repository or cites the
development history (issue trackers), and the held-out protocol it cites is in docs/."""

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: user-facing paths (README, docs, the package, the workflow, configs, data and reference tables)
USER_FACING = [
    "README.md",
    "docs",
    "src",
    "workflow",
    "config",
    "data",
    "reference",
    "profiles",
    "Snakefile",
    "pyproject.toml",
    "Makefile",
]
LEAK = re.compile(r"/work/|\.\./shared|\b[Ii]ssues? #?\d+|VALIDATION\.md")


def test_no_path_outside_the_repository_and_no_issue_numbers():
    files = subprocess.run(
        ["git", "ls-files", "--", *USER_FACING], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    hits = []
    for name in files:
        path = REPO / name
        if path.suffix in {".h5", ".png", ".npz"} or not path.is_file():
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        for k, line in enumerate(text.splitlines(), 1):
            if LEAK.search(line):
                hits.append(f"{name}:{k}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits)


def test_the_held_out_protocol_is_in_docs():
    text = (REPO / "docs" / "validation.md").read_text()
    for needed in (
        "leave one frequency out",
        "leave one temperature out",
        "bootstrap",
        "noise floor",
        "What must not leak",
    ):
        assert needed in text
