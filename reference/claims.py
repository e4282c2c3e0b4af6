"""The claims file: every number a reader sees, tied to the committed table it comes from.

``reference/claims/*.yaml`` (one file per page or folder, merged) list, per user-facing page (README.md, reference/*/README.md,
docs/), the numbers that state a result: the sentence's text as written (``text``, matched
with its whitespace collapsed), the committed tables it comes from (``tables``: a name for each
path under the repository, read as a DataFrame, or a dict for ``.json``), a Python expression
that recomputes the numbers from them (``expr``, evaluated with the tables' names, ``np``,
``pd`` and the helpers below; it returns one number per number of ``text``, in reading order,
or per ``numbers`` when only some are claimed), the tolerance (``tol``, absolute, default half
a unit of the last digit written; or ``rtol``; ``bound: upper`` for a number written as a bound
that holds, "within 0.024 %": at or above the value, by less than a unit of its last digit), and
the run that made the tables (``run``: a
key of ``runs``, each with its date and command). Numbers of a page that state no result (an
input, a setting, an equation number, the paper's own values) are listed under ``not_results``
with the reason (``text``, or a regular expression ``pattern`` for equation numbers and the
like); numbers that are dated records of a run whose raw output is not committed
(a whole invocation's wall time, a measurement on an earlier commit named in the sentence) are
listed under ``records`` with their run. Pages listed in ``covered`` must have every number of
their prose (outside code) in a claim, ``not_results`` or ``records``.

    python reference/claims.py            # check every claim; list the numbers not covered

The test (tests/unit/test_claims.py) runs the same checks: a changed table fails it until the
text follows.
"""

from __future__ import annotations

import json
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[1]
CLAIMS = ROOT / "reference" / "claims"
#: a number as written: thousands with commas, decimals, exponents; a sign (+, hyphen or U+2212)
#: counts only where no word character or digit precedes it (1.05-1.32 is a range)
NUMBER = re.compile(r"(?<![\w.,])(?:[−+-](?=\d))?(?:\d{1,3}(?:,\d{3})+(?!\d)|\d+)(?:\.\d+)?(?:[eE][−-]?\d+)?(?![\w])")


def collapse(text: str) -> str:
    """Whitespace runs as one space (a sentence wraps across lines)."""
    return re.sub(r"\s+", " ", text).strip()


def prose(text: str) -> str:
    """A page without its code: fenced blocks and inline code spans blanked (same length, so
    that positions still match the page)."""

    def blank(m):
        return re.sub(r"[^\n]", " ", m.group(0))

    text = re.sub(r"```.*?```", blank, text, flags=re.S)
    text = re.sub(r"`[^`]*`", blank, text)
    # dates (a claim's date is its run's) and version numbers (pyvisco 1.0.4) state no result
    return re.sub(r"\b\d{4}-\d{2}-\d{2}\b|\b\d+\.\d+\.\d+\b", blank, text)


def parse(token: str) -> float:
    """The value of a number as written."""
    return float(token.replace(",", "").replace("−", "-").lstrip("+"))


def numbers_in(text: str) -> list[str]:
    return NUMBER.findall(prose(text))


def half_unit(token: str) -> float:
    """Half a unit of the last digit written (4.91 -> 0.005, 9,695 -> 0.5, 1.5e-4 -> 5e-6)."""
    t = token.replace(",", "").replace("−", "-").lstrip("+-")
    mant, _, exp = t.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (-decimals + (int(exp) if exp else 0))


# helpers available to the expressions
def pct(x) -> float:
    """100 x."""
    return 100.0 * float(x)


def rng(values) -> list[float]:
    """[min, max] of values (a range as written, "538–554")."""
    v = np.asarray(list(values), float)
    return [float(np.nanmin(v)), float(np.nanmax(v))]


def one(frame: pd.DataFrame, **where):
    """The single row of ``frame`` whose columns equal ``where`` (floats within 1e-9)."""
    sel = np.ones(len(frame), bool)
    for k, v in where.items():
        col = frame[k]
        sel &= np.isclose(col.astype(float), float(v), rtol=0, atol=1e-9) if isinstance(v, (int, float)) else (col == v)
    rows = frame[sel]
    if len(rows) != 1:
        raise ValueError(f"{len(rows)} rows match {where}")
    return rows.iloc[0]


def tmean(values, level: float = 0.95) -> list[float]:
    """[mean, low, high] of values with the t(n-1) interval of the mean (a paired difference
    over mixes, "+4.8 points, -2.7 to +12.4")."""
    from asphalt_nscd.diagnosis.scores import t_interval

    v = np.asarray(list(values), float)
    v = v[np.isfinite(v)]
    return [float(v.mean()), *t_interval(v, level)]


def paired(per_mix: pd.DataFrame, a: str, b: str, column: str) -> list[float]:
    """:func:`tmean` of the per-mix difference a - b of ``column`` (reference/forecast/*_per_mix.csv:
    one row per model label and mix, every temperature together where temperature_C is empty)."""
    e = per_mix[per_mix["temperature_C"].isna() & (per_mix["binder_route"] == "curve")]
    w = e.pivot_table(index="mix_id", columns="label", values=column)
    return tmean((w[a] - w[b]).dropna())


def lower95(k, n) -> float:
    """The one-sided exact (Clopper-Pearson) 95 % lower bound of a proportion k/n, in % (a
    detection count's power shown, "90/90 (>= 96.7 %)")."""
    from asphalt_nscd.diagnosis.bench import lower_bound

    return 100.0 * lower_bound(int(k), int(n))


def upper95(k, n) -> float:
    """The one-sided exact (Clopper-Pearson) 95 % upper bound of a proportion k/n, in % (a
    false-alarm count's bound, "3/100 (<= 7.6 %)")."""
    from asphalt_nscd.diagnosis.bench import upper_bound

    return 100.0 * upper_bound(int(k), int(n))


HELPERS = {
    "np": np,
    "pd": pd,
    "math": math,
    "pct": pct,
    "rng": rng,
    "one": one,
    "tmean": tmean,
    "paired": paired,
    "lower95": lower95,
    "upper95": upper95,
}


def read_table(path: Path):
    if path.suffix == ".json":
        return json.loads(path.read_text())
    if path.suffix == ".jsonl":
        return pd.read_json(path, lines=True)
    return pd.read_csv(path)


@dataclass
class Result:
    claim: dict
    ok: bool
    message: str = ""
    pairs: list = field(default_factory=list)


SECTIONS = ("covered", "claims", "not_results", "records")


def load(path: Path = CLAIMS) -> dict:
    """The claims files of ``path`` (a directory of ``*.yaml``, or one file) merged: lists
    concatenated, ``runs`` joined (a run defined twice is an error)."""
    files = sorted(path.glob("*.yaml")) if path.is_dir() else [path]
    out: dict = {k: [] for k in SECTIONS}
    out["runs"] = {}
    for f in files:
        part = yaml.safe_load(f.read_text()) or {}
        for k in SECTIONS:
            out[k] += part.get(k) or []
        for key, run in (part.get("runs") or {}).items():
            if key in out["runs"]:
                raise ValueError(f"{f.name}: run {key!r} defined twice")
            out["runs"][key] = run
    return out


def evaluate(claim: dict, root: Path = ROOT, pages: dict | None = None, tables: dict | None = None) -> Result:
    """Check one claim: its text is on its page, and its expression, evaluated on the tables
    under ``root``, gives the numbers written within tolerance."""
    pages = {} if pages is None else pages
    tables = {} if tables is None else tables
    name = claim["file"]
    if name not in pages:
        pages[name] = collapse((ROOT / name).read_text())
    text = collapse(claim["text"])
    if text not in pages[name]:
        return Result(claim, False, f"{name}: text not found: {text[:90]!r}")
    written = [str(x) for x in claim.get("numbers", numbers_in(text))]
    missing = [w for w in written if w not in numbers_in(text)]
    if missing:
        return Result(claim, False, f"{name}: numbers {missing} are not in the text {text[:60]!r}")
    env = dict(HELPERS)
    for key, rel in (claim.get("tables") or {}).items():
        p = root / rel
        if p not in tables:
            tables[p] = read_table(p)
        env[key] = tables[p]
    try:
        got = eval(claim["expr"], env)  # noqa: S307 - the project's own claims file
    except Exception as exc:  # noqa: BLE001 - reported as a failed claim
        return Result(claim, False, f"{name}: {text[:60]!r}: expression failed: {type(exc).__name__}: {exc}")
    got = list(np.ravel(np.asarray(got, dtype=float))) if np.ndim(got) else [float(got)]
    if len(got) != len(written):
        return Result(claim, False, f"{name}: {text[:60]!r}: {len(written)} numbers written, {len(got)} computed")
    bad, pairs = [], []
    for w, g in zip(written, got):
        value = parse(w)
        tol = claim.get("tol", half_unit(w))
        if "rtol" in claim:
            tol = max(tol if "tol" in claim else 0.0, claim["rtol"] * abs(g))
        pairs.append((w, g))
        if claim.get("bound") == "upper":
            ok = math.isfinite(g) and value - 2 * half_unit(w) * (1 + 1e-9) <= g <= value * (1 + 1e-12)
            if not ok:
                bad.append(f"{w} (table: {g:.6g}, an upper bound within a unit of its last digit)")
            continue
        if not (math.isfinite(g) and abs(g - value) <= tol * (1 + 1e-9)):
            bad.append(f"{w} (table: {g:.6g}, tolerance {tol:.3g})")
    if bad:
        return Result(claim, False, f"{name}: {text[:70]!r}: " + "; ".join(bad), pairs)
    return Result(claim, True, "", pairs)


def check_claims(data: dict, root: Path = ROOT) -> list[Result]:
    """Every claim of ``data`` evaluated on the tables under ``root``; a claim's ``run`` must be
    a key of ``runs`` (its date and command)."""
    pages: dict = {}
    tables: dict = {}
    runs = data.get("runs") or {}
    out = []
    for claim in data.get("claims") or []:
        if claim.get("run") not in runs:
            out.append(Result(claim, False, f"{claim.get('file')}: run {claim.get('run')!r} is not in runs"))
            continue
        out.append(evaluate(claim, root, pages, tables))
    return out


def uncovered(data: dict) -> list[str]:
    """The numbers of the ``covered`` pages' prose that no claim or ``not_results`` entry covers
    ("page: line: number in context")."""
    spans: dict[str, list] = {}
    for entry in [e for k in ("claims", "not_results", "records") for e in data.get(k) or []]:
        if "text" in entry:
            spans.setdefault(entry["file"], []).append(collapse(entry["text"]))
    out = []
    for name in data.get("covered") or []:
        raw = (ROOT / name).read_text()
        text = prose(raw)
        # positions of the collapsed page mapped back to the raw page
        flat, where = [], []
        prev_space = False
        for i, ch in enumerate(raw):
            if ch.isspace():
                if not prev_space:
                    flat.append(" ")
                    where.append(i)
                prev_space = True
            else:
                flat.append(ch)
                where.append(i)
                prev_space = False
        page = "".join(flat)
        covered = np.zeros(len(raw) + 1, bool)
        for entry in data.get("not_results") or []:
            if entry["file"] == name and "pattern" in entry:
                for m in re.finditer(entry["pattern"], raw):
                    covered[m.start() : m.end()] = True
        for snippet in spans.get(name, []):
            start = page.find(snippet)
            while start >= 0:
                covered[where[start] : where[start + len(snippet) - 1] + 1] = True
                start = page.find(snippet, start + 1)
        for m in NUMBER.finditer(text):
            if not covered[m.start() : m.end()].all():
                line = raw.count("\n", 0, m.start()) + 1
                ctx = collapse(raw[max(0, m.start() - 40) : m.end() + 25])
                out.append(f"{name}:{line}: {m.group(0)}  ({ctx})")
    return out


def main() -> int:
    data = load()
    results = check_claims(data)
    failed = [r for r in results if not r.ok]
    for r in failed:
        print("FAIL", r.message)
    missing = uncovered(data)
    for m in missing:
        print("NOT COVERED", m)
    print(f"{len(results) - len(failed)} of {len(results)} claims hold; {len(missing)} numbers not covered")
    return 1 if failed or missing else 0


if __name__ == "__main__":
    sys.exit(main())
