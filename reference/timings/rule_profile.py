"""Per-rule profile of a finished workflow run: jobs, wall and CPU seconds of each rule from Snakemake's
``benchmark:`` records (``benchmarks/**/*.tsv``, matched to the rules by their benchmark patterns in
workflow/rules/*.smk), beside the exact CPU of each command from ``benchmarks/process_cpu.jsonl``
(``getrusage`` of the process and the workers it waited for, interpreter start-up included; Snakemake's
records sample every few seconds and miss short jobs' CPU).

    .venv/bin/python reference/timings/rule_profile.py RUN_DIR -o reference/timings/make_run_rules.csv

Columns: rule, jobs (benchmark records), wall_s (sum of the jobs' wall times), cpu_s_benchmark
(Snakemake's sampled CPU), command (the asphalt-nscd command the rule runs), processes, cpu_s (exact,
sum over the command's processes), cpu_s_per_process, cpu_s_least_process (the least CPU of one of the
rule's processes: what one job costs at the least, its start-up included, so processes x it bounds
what batching the rule's jobs into one process could save). Rules sorted by cpu_s, then by wall_s.
A rule with no benchmark record (several forecast rules) has jobs 0 and its processes' CPU; a
benchmark record matched by no rule keeps its path as its rule.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

import pandas as pd

REPO = Path(__file__).resolve().parents[2]


#: the columns of a Snakemake benchmark record this profile reads: wall seconds and sampled CPU seconds
BENCHMARK_COLUMNS = ("s", "cpu_time")

#: a rule's header: ``rule name:`` or ``checkpoint name:``, indented where it sits under an ``if``
RULE_HEADER = re.compile(r"^[ \t]*(?:rule|checkpoint) (\w+):[ \t]*$", flags=re.M)


def rule_blocks(rules_dir: Path) -> dict[str, str]:
    """Rule name -> its text, from its header to the next rule's header (or the file's end)."""
    out = {}
    for smk in sorted(rules_dir.glob("*.smk")):
        text = smk.read_text()
        heads = list(RULE_HEADER.finditer(text))
        for head, nxt in zip(heads, heads[1:] + [None]):
            out[head.group(1)] = text[head.end() : nxt.start() if nxt else len(text)]
    return out


def benchmark_patterns(blocks: dict[str, str]) -> dict[str, re.Pattern]:
    """Rule name -> regular expression of its benchmark path (a wildcard matches one or more path parts:
    ``{where}`` may be ``results/forecast``), from the rules' texts of :func:`rule_blocks`."""
    out = {}
    for rule, block in blocks.items():
        b = re.search(r"benchmark:\s*\"([^\"]+)\"", block)
        if b:
            parts = re.split(r"(\{[^}]+\})", b.group(1))
            regex = "".join(".+" if p.startswith("{") else re.escape(p) for p in parts)
            out[rule] = re.compile(regex + "$")
    return out


def rule_commands(blocks: dict[str, str]) -> dict[str, tuple[str, set[str]]]:
    """Rule name -> (the asphalt-nscd command its shell runs, the options written in its shell), from the
    rules' texts of :func:`rule_blocks`."""
    out = {}
    for rule, block in blocks.items():
        shell = block.split("shell:", 1)[-1]
        c = re.search(r"asphalt-nscd ([a-z0-9-]+)", shell)
        if c:
            opts = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", shell))
            # an option written with a literal value (--grid sweep) must have that value
            opts |= {f"{o}={v}" for o, v in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*) ([a-z][a-z0-9_]*)\b", shell)}
            out[rule] = (c.group(1), opts)
    return out


def rule_of(argv: list[str], commands: dict[str, tuple[str, set[str]]]) -> str | None:
    """The rule whose command is ``argv[0]`` and whose written options all appear in ``argv`` (the one
    with most options where several do)."""
    given = set(argv) | {f"{a}={b}" for a, b in zip(argv, argv[1:])}
    fits = [(len(opts), r) for r, (c, opts) in commands.items() if c == argv[0] and opts <= given]
    return max(fits)[1] if fits else None


def _benchmark_record(tsv: Path) -> pd.DataFrame:
    """One job's Snakemake benchmark table, ``s`` and ``cpu_time`` as numbers (``cpu_time`` ``NA``, which
    Snakemake writes where it measured none, as 0); ``ValueError`` naming the file if it lacks the columns
    read, and naming the file, row and column of a value that is not a non-negative number."""
    try:
        b = pd.read_csv(tsv, sep="\t", dtype=str, keep_default_na=False)  # the values as written
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError) as err:
        raise ValueError(f"{tsv}: not a Snakemake benchmark table ({err})") from None
    missing = [c for c in BENCHMARK_COLUMNS if c not in b.columns]
    if missing:
        raise ValueError(
            f"{tsv}: a Snakemake benchmark table needs the columns {', '.join(BENCHMARK_COLUMNS)}; "
            f"missing {', '.join(missing)} (header: {', '.join(map(str, b.columns))})"
        )
    for column in BENCHMARK_COLUMNS:
        raw = b[column]
        values = pd.to_numeric(raw, errors="coerce")
        allowed_na = raw.eq("NA") if column == "cpu_time" else pd.Series(False, index=raw.index)
        bad = ~((values >= 0) | allowed_na)
        if bad.any():
            row = int(bad.to_numpy().argmax())
            what = "a number of seconds >= 0" + (" or NA" if column == "cpu_time" else "")
            raise ValueError(f"{tsv}, row {row + 1}, column {column}: expected {what}, got {raw.iloc[row]!r}")
        b[column] = values.fillna(0.0)
    return b


def _process_records(log: Path) -> list[tuple[list[str], float]]:
    """(argv, user + system CPU seconds) of each line of ``process_cpu.jsonl``; ``ValueError`` naming the
    file, the line and what was expected."""
    out = []
    for number, line in enumerate(log.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            r = json.loads(line)
            argv, cpu = r["argv"], float(r["user_s"]) + float(r["system_s"])
            if not (isinstance(argv, list) and argv and all(isinstance(a, str) for a in argv)):
                raise TypeError("argv")
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
            raise ValueError(
                f"{log}, line {number}: expected a JSON object with argv (a non-empty list of strings), "
                f"user_s and system_s (seconds); {type(err).__name__}: {err}"
            ) from None
        out.append((argv, cpu))
    return out


def profile(run: Path, rules_dir: Path) -> pd.DataFrame:
    """The per-rule table of the run in ``run`` (module docstring), the rules read from ``rules_dir``.

    Raises ``ValueError`` naming the folder when it holds no benchmark record, and naming the file (and
    line) of a record that cannot be read."""
    folder = run / "benchmarks"
    tsvs = sorted(folder.rglob("*.tsv")) if folder.is_dir() else []
    log = folder / "process_cpu.jsonl"
    if not tsvs and not log.is_file():
        raise ValueError(
            f"{folder}: no benchmark records (expected Snakemake's benchmarks/**/*.tsv or "
            "benchmarks/process_cpu.jsonl of a finished run)"
        )
    blocks = rule_blocks(rules_dir)
    if not blocks:
        raise ValueError(f"{rules_dir}: no rule in its *.smk files")
    patterns = benchmark_patterns(blocks)
    commands = rule_commands(blocks)
    rows = defaultdict(lambda: {"jobs": 0, "wall_s": 0.0, "cpu_s_benchmark": 0.0})
    for tsv in tsvs:
        rel = tsv.relative_to(run).as_posix()
        matches = [r for r, p in patterns.items() if p.match(rel)]
        # the most specific pattern: the longest literal part
        rule = max(matches, key=lambda r: len(patterns[r].pattern.replace(".+", ""))) if matches else rel
        b = _benchmark_record(tsv)
        rows[rule]["jobs"] += len(b)
        rows[rule]["wall_s"] += float(b["s"].sum())
        rows[rule]["cpu_s_benchmark"] += float(b["cpu_time"].sum())
    exact = defaultdict(lambda: [0, 0.0, float("inf")])
    if log.is_file():
        for argv, cpu in _process_records(log):
            rule = rule_of(argv, commands) or f"(command {argv[0]})"
            exact[rule][0] += 1
            exact[rule][1] += cpu
            exact[rule][2] = min(exact[rule][2], cpu)
    for rule in exact:
        rows[rule]  # a command with no benchmark record still gets its row
    table = pd.DataFrame([{"rule": k, **v} for k, v in rows.items()])
    table["command"] = table["rule"].map({r: c for r, (c, _) in commands.items()})
    table["processes"] = table["rule"].map({r: v[0] for r, v in exact.items()})
    table["cpu_s"] = table["rule"].map({r: v[1] for r, v in exact.items()})
    table["cpu_s_per_process"] = table["cpu_s"] / table["processes"]
    table["cpu_s_least_process"] = table["rule"].map({r: v[2] for r, v in exact.items()})
    table = table.sort_values(["cpu_s", "wall_s"], ascending=False, na_position="last")
    return table.round(2)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="working directory of the run (holding benchmarks/)")
    ap.add_argument("--rules", type=Path, default=REPO / "workflow" / "rules", help="the rule files' folder")
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args(argv)
    try:
        table = profile(args.run, args.rules)
    except ValueError as err:
        ap.exit(2, f"rule_profile.py: error: {err}\n")
    out = Path(args.output)
    tmp = out.with_name(out.name + ".tmp")
    table.to_csv(tmp, index=False)
    tmp.replace(out)  # a failed run leaves no half-written table
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
