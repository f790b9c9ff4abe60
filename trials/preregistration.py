"""The pre-registration `trials design` writes (preregistration.md): the hypotheses, the design and its allocation rule,
the planned analysis, the sample size and its power, the stopping, exclusion and deviation rules, and the bindings: the
design's digest, the analysis plan's digest and the sealed key's commitment.

The SHA-256 of the file is the one digest the experimenter records outside the study. Opening the key checks it, and
every report checks the bindings against the study's files. Editing the plan, the design or the key shows, whoever
edits them; so does rewriting this file to match, since its digest then differs from the one recorded outside."""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import string
from typing import TYPE_CHECKING

from analysis.plan import AnalysisPlan
from analysis.records import DESIGN_BINDING, KEY_BINDING, PLAN_BINDING, Registration
from designs.blinding import WHOLE_KEY, canonical_bytes
from designs.factors import CategoricalFactor, DiscreteFactor, Factor, FixedFactor
from designs.spec import StudySpec, read_spec
from trials.analysis_plan import plan_in_force
from trials.atomic import write_files
from trials.errors import StudyError
from trials.study import ALLOCATION, PREREGISTRATION, SPEC, StudyFolder, design_digest

if TYPE_CHECKING:
    from trials.power.planned import PlannedPower

#: A line of the Bindings section: `- <name>: `<sha256>``.
_BINDING_LINE = re.compile(rf"^- ({'|'.join(map(re.escape, (DESIGN_BINDING, PLAN_BINDING, KEY_BINDING)))}): `([0-9a-f]{{64}})`", re.MULTILINE)


def register(folder: StudyFolder, planned: PlannedPower | None) -> str:
    """Write the pre-registration of the study `trials design` just wrote (from its public files and the key's digest);
    returns its SHA-256."""
    spec = read_spec(folder.path(SPEC))
    design = folder.read_design()
    plan, _ = plan_in_force(folder.path(SPEC), spec, design)
    text = _document(spec, design, plan, planned, _bindings(folder)).encode()
    write_files({folder.path(PREREGISTRATION): text})
    return hashlib.sha256(text).hexdigest()


def registered_lines(digest: str, blinded: bool) -> str:
    """What `trials design` prints about the pre-registration: the digest to record, and what it guards."""
    opened = (" `trials report --unblind --commitment <it>` opens the sealed key only against it." if blinded else "")
    return (f"Pre-registration {PREREGISTRATION}, sha256\n  {digest}\nRecord this digest outside the study folder (a registry, "
            f"an e-mail): it binds the analysis plan, the design and the sealed key, and every report checks them against it.{opened}")


def registration(folder: StudyFolder, recorded: str | None = None) -> Registration | None:
    """The study's pre-registration and how its files stand against it, and against the digest `recorded` outside it
    when given; None for a study designed by an earlier release (no preregistration.md)."""
    path = folder.path(PREREGISTRATION)
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return None
    bound = dict(_BINDING_LINE.findall(text.decode("utf-8", errors="replace")))
    now = _bindings(folder)
    differs = tuple(name for name in (DESIGN_BINDING, PLAN_BINDING, KEY_BINDING) if bound.get(name) != now.get(name))
    digest = hashlib.sha256(text).hexdigest()
    return Registration(PREREGISTRATION, digest, differs, None if recorded is None else secrets.compare_digest(digest, recorded.strip().lower()))


def check_recorded(folder: StudyFolder, recorded: str) -> str:
    """Check the study against the pre-registration digest recorded outside it, before its key is opened; returns the
    sentence the report prints.

    Raises:
        StudyError: not 64 hex digits; the sealed key's commitment given instead; preregistration.md not the file whose
            digest was recorded; or a design or key that differs from what it binds.
    """
    found = registration(folder)
    assert found is not None, "only a registered study is checked against a registration digest"
    value = recorded.strip().lower()
    if len(value) != 64 or any(c not in string.hexdigits for c in value):
        raise StudyError(f"--commitment: expected the 64 hex digits of the pre-registration digest `trials design` printed, got {recorded!r}")
    if not secrets.compare_digest(found.digest, value):
        key = folder.read_design().get("blinding", {}).get("commitment", {}).get("digest")
        if key is not None and secrets.compare_digest(str(key), value):
            raise StudyError("--commitment: that is the sealed key's commitment; this study has a pre-registration, so give the "
                             f"digest `trials design` printed for it (the SHA-256 of {PREREGISTRATION}), which binds the key too")
        raise StudyError(f"{folder.path(PREREGISTRATION)} does not match the digest you recorded ({value[:16]}...): it, and so the "
                         "study it binds, was changed after `trials design` printed the digest, or the value belongs to another study")
    changed = [name for name in found.differs if name != PLAN_BINDING]
    if changed:
        raise StudyError(f"the {' and the '.join(changed)} of {folder.root} differ from what {PREREGISTRATION} registered: changed after "
                         "the pre-registration, so the key is not opened")
    return (f"The pre-registration ({PREREGISTRATION}, sha256 {found.digest[:16]}...) matched the digest recorded outside the "
            "study, and the design and sealed key it binds are unchanged.")


def _bindings(folder: StudyFolder) -> dict[str, str]:
    """The digests of what a pre-registration binds, from the study's files as they are now (a key that cannot be read
    has none)."""
    design = folder.read_design()
    spec = read_spec(folder.path(SPEC))
    plan, _ = plan_in_force(folder.path(SPEC), spec, design)
    found = {DESIGN_BINDING: design_digest(design)["sha256"], PLAN_BINDING: plan.digest()}
    blinding = design.get("blinding")
    if blinding:
        try:
            key = json.loads(folder.path(ALLOCATION).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return found
        if blinding.get("commitment", {}).get("algorithm") == WHOLE_KEY:
            found[KEY_BINDING] = hashlib.sha256(canonical_bytes(key)).hexdigest()
    return found


def _document(spec: StudySpec, design: dict, plan: AnalysisPlan, planned: PlannedPower | None, bound: dict[str, str]) -> str:
    blinding = design.get("blinding")
    diagnostics = design.get("diagnostics", {})
    factors = "\n".join(f"- {f.name}: {_levels(f)}" for f in spec.factors)
    if plan.factor:
        hypotheses = (f"- H0: {plan.factor} has no effect on whether a run's judges call it socially compliant: every run's share "
                      "of yes would have been the same under the other arm.\n"
                      f"- H1: it has an effect (two-sided), tested at alpha {plan.alpha:g}.")
    else:
        hypotheses = f"- For each term of the model `{plan.model}`: H0, it has no effect on the odds of a yes; H1, it has one (alpha {plan.alpha:g})."
    allocation = (f"{blinding['factor']} is allocated to the runs by the design and shown only as arm labels "
                  f"({', '.join(blinding['arms'])}); the key naming each arm's controller is sealed in sealed/ and committed to "
                  "(the sealed key's binding below). Nobody on the field needs it; it is opened once every run has finished."
                  if blinding else "The study is not blinded: the plan names each run's levels.")
    power = ("\n".join(planned.lines()) if planned is not None else
             "Not computed with this design (`trials design --power 0`, `--augment`, or a plan that compares no arms).")
    table = "\n".join(f"- {key}: {json.dumps(value)}" for key, value in plan.table().items())
    return f"""# Pre-registration: {spec.name}

Written by `trials design`. Its SHA-256, printed by `trials design`, is the digest to record outside the study (a
registry, an e-mail): opening the sealed key checks it, and every report checks the study against the bindings below.

## Hypotheses

{hypotheses}

## Design

{spec.runs} runs, model `{spec.model}`, criterion {spec.criterion}, design seed {design.get('seed')}; D-efficiency
{diagnostics.get('d_efficiency', float('nan')):.4f}. Factors:

{factors}

## Allocation

{allocation}

## Planned analysis

Primary test: {plan.describe_test()}. The outcome is each judgment's answer to "socially compliant?"; the run is the unit.
Every convention, as study.toml's [analysis] table holds it:

{table}

## Sample size and power

{spec.runs} runs, as designed.

```
{power}
```

## Stopping rules

- The study ends when every run of the plan has finished. No interim look is planned: a look before then
  (`trials report --interim REASON`) is recorded with its reason and shown in every later report.
- A live run stops on any doubt (stale or invalid sensors, an e-stop, a lost link, the protective field, the time
  limit); a run that ends early is flagged as a deviation.

## Exclusion rules

- Runs played from an external robot log are not compared between arms.
- People's judgments and scores recorded after the key was first opened are counted apart and left out.
- Simulated judgments are not used in a study whose runs were driven live, unless entered with `--allow-simulated`.
- A run decided `rerun` is replaced by its rerun; its first attempt is kept in superseded/.

## Deviations

Every live run's manipulation check and early end is logged in live_checks.csv; the operator decides each flagged run
(`trials deviation CODE --stands|--rerun --reason TEXT`) before the key is opened, and the report counts every
attempt per arm. Adding runs (`trials design --augment`) writes a new pre-registration with a new digest.

## Bindings

- {DESIGN_BINDING}: `{bound[DESIGN_BINDING]}` (design.json: the runs, their arms, the plan's digest and the commitments)
- {PLAN_BINDING}: `{bound[PLAN_BINDING]}` (study.toml's [analysis] table as canonical JSON)
""" + (f"- {KEY_BINDING}: `{bound[KEY_BINDING]}` (sealed/allocation.json as canonical JSON)\n" if KEY_BINDING in bound else "")


def _levels(factor: Factor) -> str:
    """A factor's levels, range or fixed value, in words."""
    if isinstance(factor, FixedFactor):
        return f"held at {_value(factor.value)}"
    if isinstance(factor, CategoricalFactor | DiscreteFactor):
        return ", ".join(map(_value, factor.levels))
    return f"{_value(factor.low)} to {_value(factor.high)} ({factor.kind})"


def _value(value: object) -> str:
    return f"{value:g}" if isinstance(value, int | float) else str(value)
