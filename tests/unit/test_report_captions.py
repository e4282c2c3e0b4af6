"""Every caption of the HTML report (workflow/report/*.rst) is clean reStructuredText:
docutils renders it without a warning (a caption writing |E*| unescaped is a substitution
reference, shown as an error box under the figure in the report)."""

import io
from pathlib import Path

import pytest
from docutils.core import publish_parts
from docutils.utils import SystemMessage

CAPTIONS = sorted((Path(__file__).resolve().parents[2] / "workflow" / "report").glob("*.rst"))


@pytest.mark.parametrize("path", CAPTIONS, ids=lambda p: p.name)
def test_caption_renders_without_docutils_messages(path):
    stream = io.StringIO()
    try:
        publish_parts(
            path.read_text(),
            writer_name="html",
            settings_overrides={"halt_level": 2, "report_level": 2, "warning_stream": stream},
        )
    except SystemMessage as exc:
        pytest.fail(f"{path.name}: {exc}")
    assert not stream.getvalue(), f"{path.name}: {stream.getvalue()}"


def test_every_report_caption_is_used():
    rules = "".join(p.read_text() for p in (CAPTIONS[0].parents[1] / "rules").glob("*.smk"))
    rules += (CAPTIONS[0].parents[2] / "Snakefile").read_text()
    unused = [p.name for p in CAPTIONS if p.name not in rules]
    assert not unused, f"captions no rule uses: {unused}"
