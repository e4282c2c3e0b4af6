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


def benchmark_patterns(rules_dir: Path) -> dict[str, re.Pattern]:
    """Rule name -> regular expression of its benchmark path (a wildcard matches one or more path parts:
    ``{where}`` may be ``results/forecast``)."""
    out = {}
    for rule, block in rule_blocks(rules_dir).items():
        b = re.search(r"benchmark:\s*\"([^\"]+)\"", block)
        if b:
            parts = re.split(r"(\{[^}]+\})", b.group(1))
            regex = "".join(".+" if p.startswith("{") else re.escape(p) for p in parts)
            out[rule] = re.compile(regex + "$")
    return out


def rule_commands(rules_dir: Path) -> dict[str, tuple[str, set[str]]]:
    """Rule name -> (the asphalt-nscd command its shell runs, the options written in its shell)."""
    out = {}
    for rule, block in rule_blocks(rules_dir).items():
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


def profile(run: Path, rules_dir: Path) -> pd.DataFrame:
    """The per-rule table of the run in ``run`` (module docstring), the rules read from ``rules_dir``."""
    patterns = benchmark_patterns(rules_dir)
    commands = rule_commands(rules_dir)
    rows = defaultdict(lambda: {"jobs": 0, "wall_s": 0.0, "cpu_s_benchmark": 0.0})
    for tsv in sorted((run / "benchmarks").rglob("*.tsv")):
        rel = tsv.relative_to(run).as_posix()
        matches = [r for r, p in patterns.items() if p.match(rel)]
        # the most specific pattern: the longest literal part
        rule = max(matches, key=lambda r: len(patterns[r].pattern.replace(".+", ""))) if matches else rel
        b = pd.read_csv(tsv, sep="\t")
        rows[rule]["jobs"] += len(b)
        rows[rule]["wall_s"] += float(b["s"].sum())
        rows[rule]["cpu_s_benchmark"] += float(pd.to_numeric(b["cpu_time"], errors="coerce").fillna(0).sum())
    exact = defaultdict(lambda: [0, 0.0, float("inf")])
    log = run / "benchmarks" / "process_cpu.jsonl"
    if log.exists():
        for line in log.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                rule = rule_of(r["argv"], commands) or f"(command {r['argv'][0]})"
                cpu = r["user_s"] + r["system_s"]
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
    table = profile(args.run, args.rules)
    table.to_csv(args.output, index=False)
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
