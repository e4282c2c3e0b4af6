"""Workflow configuration files: one complete default and overlays merged over it.

``config/config.yaml`` is the one complete configuration (every key, with its meaning);
``config/paper.yaml``, ``config/smoke.yaml`` and ``config/table.yaml`` are overlays holding
only the keys they change. Snakemake reads ``config/config.yaml`` (the Snakefile's
``configfile:``) and merges every ``--configfile`` file over it in order with
:func:`snakemake.utils.update_config`. The asphalt-nscd commands that read a workflow config
(``--config``) do the same through :func:`load`, so that a command and the workflow given the
same files see the same configuration:

* nested mappings are merged key by key, recursively;
* any other value (a list, a number, a string, null) of a later file replaces the earlier one;
* a (non-empty) mapping given where an earlier file holds a non-mapping value replaces it.

Snakemake starts its merge from the ``--configfile`` files, so their keys come first; the
Snakefile puts the keys back in config/config.yaml's order (:func:`restore_default_order`),
the order :func:`load` gives, so that the run's configuration file the jobs read
(:func:`write_run_config`, named by its hash) is the same whichever files gave its values. Files ending in ``.json`` are read as
JSON, every other file as YAML.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from pathlib import Path

from .io import InputError

#: the complete default configuration, relative to the working directory (the repository root),
#: as the Snakefile's ``configfile:``
DEFAULT_CONFIG = Path("config") / "config.yaml"

#: top-level sections of a workflow config (workflow/schemas/config.schema.yaml)
SECTIONS = ("measured", "lab", "calibration", "nscd", "sample", "campaign", "harmonic", "diagnosis", "forecast")


def read(path: str | Path) -> dict:
    """The mapping held by one config file (YAML, or JSON if the name ends in ``.json``); an
    empty file is an empty mapping.

    Raises
    ------
    InputError
        naming the file: missing or unreadable, not valid YAML/JSON, or not a mapping at the top.
    """
    import yaml

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the config file ({exc})") from exc
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml_load(text)
    except (ValueError, yaml.YAMLError) as exc:
        kind = "JSON" if path.suffix == ".json" else "YAML"
        raise InputError(f"{path}: not valid {kind} ({exc})") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a mapping of config sections at the top, got {type(data).__name__}")
    return data


def yaml_load(text: str):
    """``yaml.safe_load`` of ``text`` through libyaml's ``CSafeLoader`` where PyYAML has it
    (the same safe schema, about ten times faster: a job reads the config and the schemas at
    start-up), else the pure-Python ``SafeLoader``.

    Raises
    ------
    yaml.YAMLError if ``text`` is not valid YAML.
    """
    import yaml

    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def merge(base: Mapping, overlay: Mapping) -> dict:
    """``overlay`` merged over ``base`` as :func:`snakemake.utils.update_config` merges a
    ``--configfile`` over the config (module docstring; the same algorithm, so also its edge
    case: an empty mapping leaves the value below it as it is). A new dict: neither argument is
    modified and the result shares no mutable value with them."""

    def merge_into(target, over: Mapping):
        for key, value in over.items():
            if not isinstance(target, Mapping):
                target = {}
            if isinstance(value, Mapping):
                target[key] = merge_into(target.get(key, {}), value)
            else:
                target[key] = value
        return target

    return merge_into(copy.deepcopy(dict(base)), copy.deepcopy(overlay))


def load(paths, *, default: str | Path | None = DEFAULT_CONFIG) -> dict:
    """The configuration of the config files ``paths`` (one path or a sequence), as Snakemake
    builds it from ``--configfile paths``: ``default`` (``config/config.yaml`` of the working
    directory, if it exists; None: no default) first, then each file of ``paths`` merged over
    the result in order (:func:`merge`). Naming ``config/config.yaml`` itself among ``paths``
    is harmless (merging a file twice changes nothing).

    Raises
    ------
    InputError
        naming the file that is missing, unreadable, not valid YAML/JSON or not a mapping.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    cfg: dict = {}
    if default is not None and Path(default).is_file():
        cfg = read(default)
    for path in paths:
        cfg = merge(cfg, read(path))
    return cfg


def ordered_like(cfg: Mapping, reference: Mapping) -> dict:
    """``cfg`` with the keys of every mapping in the order of ``reference`` (recursively), then
    the keys ``reference`` lacks in their own order; values are not changed.

    Snakemake puts the keys of the ``--configfile`` files first (it starts from them and merges
    the Snakefile's ``configfile:`` and then them again over it), so the same configuration
    built from an overlay lists its keys in another order than config/config.yaml. The
    workflow restores config/config.yaml's order, so that the run's configuration file
    (:func:`write_run_config`) is the same whichever files gave the values.
    """
    out = {}
    for key in [k for k in reference if k in cfg] + [k for k in cfg if k not in reference]:
        value, ref = cfg[key], reference.get(key)
        out[key] = ordered_like(value, ref) if isinstance(value, Mapping) and isinstance(ref, Mapping) else value
    return out


def restore_default_order(cfg: dict, default: str | Path = DEFAULT_CONFIG) -> None:
    """Put the keys of the workflow's ``config`` (modified in place) back in the order of
    ``default`` (:func:`ordered_like`); the Snakefile calls it after its ``configfile:``.

    Raises
    ------
    InputError
        naming ``default`` if it cannot be read.
    """
    ordered = ordered_like(cfg, read(default))
    cfg.clear()
    cfg.update(ordered)


#: the workflow's schemas (top level and one per section), relative to the working directory
SCHEMA_DIR = Path("workflow") / "schemas"

#: where the workflow writes the configuration of a run (:func:`write_run_config`)
RUN_CONFIG_DIR = Path("results") / "config"


def check(cfg: Mapping, where: str, schema_dir: str | Path = SCHEMA_DIR) -> None:
    """Check a merged configuration against the workflow's schemas as Snakemake does at load
    (the Snakefile's top-level ``validate``, then each section's in workflow/rules/common.smk):
    ``config.schema.yaml``, then ``<section>.schema.yaml`` for every section that has one.
    Schemas absent from ``schema_dir`` are skipped (a command run outside a checkout).

    Raises
    ------
    InputError
        naming ``where`` (the files read), the key path and what the schema expects.
    """
    import jsonschema

    schema_dir = Path(schema_dir)
    pairs = [("", cfg, schema_dir / "config.schema.yaml")]
    pairs += [(s, cfg[s], schema_dir / f"{s}.schema.yaml") for s in cfg if isinstance(cfg.get(s), Mapping)]
    for section, value, path in pairs:
        if not path.is_file():
            continue
        schema = yaml_load(path.read_text(encoding="utf-8"))
        validator = jsonschema.validators.validator_for(schema)(schema)
        error = jsonschema.exceptions.best_match(validator.iter_errors(value))
        if error is not None:
            key = ".".join(str(k) for k in [section, *error.absolute_path] if k != "") or "(top level)"
            raise InputError(f"{where}: {key}: {error.message} (schema {path})")


def checked(paths, *, default: str | Path | None = DEFAULT_CONFIG) -> dict:
    """The configuration of the config files ``paths`` merged as :func:`load` merges them,
    checked against the workflow's schemas (:func:`check`): what a command given ``--config``
    reads, the same configuration Snakemake checks for the workflow.

    Raises
    ------
    InputError
        naming the file (missing, unreadable, not a mapping) or the key the schemas refuse.
    """
    cfg = load(paths, default=default)
    names = " ".join(str(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths))
    check(cfg, names)
    return cfg


def write_run_config(cfg: Mapping, directory: str | Path = RUN_CONFIG_DIR) -> str:
    """Write the workflow's merged, checked configuration ``cfg`` to
    ``{directory}/<first 12 hex digits of its SHA-256>.yaml`` (atomically, only if absent) and
    return that path. The Snakefile calls it once per run: the jobs read their settings from
    this file (``--config``), including any ``snakemake --config KEY=VALUE``; the name changes
    with the content, so a file is never rewritten under a running job."""
    import hashlib

    import yaml

    from .io import write_text

    text = yaml.safe_dump(json.loads(json.dumps(cfg)), sort_keys=False, allow_unicode=True)
    path = Path(directory) / f"{hashlib.sha256(text.encode()).hexdigest()[:12]}.yaml"
    if not path.is_file():
        write_text(text, path)
    return path.as_posix()


def config_option(p, values, section: str) -> None:
    """Give command ``p`` the option ``--config FILE...`` and the function ``values(cfg, args)``
    (merged, checked workflow config and the parsed command line -> argument name -> value)
    whose values become the command's defaults (:func:`asphalt_nscd.cli.with_config_values`); ``section`` names
    the config keys the values come from, for the help."""
    p.add_argument(
        "--config",
        nargs="+",
        default=None,
        metavar="FILE",
        help="workflow config files (YAML) merged as Snakemake merges --configfile (config/config.yaml "
        f"of the working directory first) and checked against the workflow's schemas: options of "
        f"this command not given here take the values of {section}",
    )
    p.set_defaults(config_values=values)
