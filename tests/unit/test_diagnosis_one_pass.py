"""``asphalt-nscd diagnose`` reads each result it is given once: the master-curve JSON and the
law JSON are read one time each (counted calls of :func:`asphalt_nscd.io.read_json`), checked
against the measured table and parsed from the same objects."""

import collections
import functools

from diagnosis_chain import cli_chain

from asphalt_nscd.cli import main


def test_diagnose_reads_each_json_once(tmp_path, monkeypatch):
    import asphalt_nscd.diagnosis.artifacts as artifacts
    import asphalt_nscd.io as io
    import asphalt_nscd.rheology.law_file as law_file

    m = tmp_path / "M.csv"
    assert main(["synth", "--seed", "5", "--schedule", "paper_2pb", "--specimens", "2", "-o", str(m)]) == 0
    chain = cli_chain(m, tmp_path / "chain")
    reads: collections.Counter = collections.Counter()
    original = io.read_json

    @functools.wraps(original)
    def counted(path, *args, **kwargs):
        reads[str(path)] += 1
        return original(path, *args, **kwargs)

    for module in (io, artifacts, law_file):
        monkeypatch.setattr(module, "read_json", counted)
    assert main(["diagnose", *chain["args"], "-o", str(tmp_path / "report.json")]) == 0
    assert reads[str(chain["search"])] == 1
    assert reads[str(chain["law"])] == 1
