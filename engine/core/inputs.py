"""The input rules of a request: what a user's JSON (a study, its reference test, a
calibration's design) must give beyond what the records themselves check. The command line
(``demscale``) and the job service (``service/spec.py``) apply these, one copy.

A record checks its own fields (:func:`engine.core.records.param` bounds, ``__post_init__``);
this module holds what only a request can break: a field a user must give although the
record has a default (a study's reference, a shear test's or a hopper's pair law), a
uniaxial test that names neither a preset nor its pair law (it would run the record's
default law, which nobody chose), and the lower bounds of a calibration's design. Every
refusal is an :class:`engine.ParameterError` (:class:`engine.core.errors.MissingField` for
what is left out) naming the field and the limit.

The rules are keyed by the records' names (their JSON ``"type"``): this module imports no
layer below ``core``.
"""

from __future__ import annotations

from .errors import MissingField, ParameterError

#: Fields a request must give although the record has a default (or has none and says
#: less), keyed by (record, field): why, said when one is left out.
REQUIRED_GIVEN: dict[tuple[str, str], str] = {
    ("StudySpec", "reference"): 'a preset named, e.g. {"preset": "quick"}, or the pair law '
    "with the other fields of the test: no study runs a default reference",
    ("ShearTest", "pair_law"): "the shear test's particle-particle law: no study runs the "
    "record's default law, which nobody chose",
    ("HopperTest", "pair_law"): "the hopper's particle-particle law: no study runs the "
    "record's default law, which nobody chose",
}

#: A uniaxial test given as JSON names a preset or gives its pair law: what it needs, and why.
PRESET_OR_PAIR_LAW = "give a preset (quick or paper) or the pair law"
PRESET_OR_PAIR_LAW_WHY = "a test of the record's defaults alone would run a law nobody chose"

#: The record a test's JSON is where it names no ``"type"``.
DEFAULT_TEST_TYPE = "UniaxialTest"

#: Lower bounds of a calibration's design (engine.calibrate's ``runs``, ``waves`` and
#: ``wave_runs``): design runs (at least 3; engine.calibration.calibrate.check_request
#: wants the parameters + 2), history-matching waves after the design, runs per wave.
DESIGN_MINIMUM: dict[str, int] = {"runs": 3, "waves": 0, "wave_runs": 1}


def _at(owner: str, field: str) -> str:
    return f"{owner}.{field}" if owner else field


def check_test_json(raw, owner: str) -> None:
    """A test as a user gives it in JSON (a study's reference, a calibration's test): the
    fields :data:`REQUIRED_GIVEN` names for its record (``"type"``; none: a uniaxial test),
    and a uniaxial test names a ``"preset"`` or gives its ``"pair_law"``. ``owner`` is the
    path of the test in the request (``"reference"``); raises
    :class:`engine.core.errors.MissingField` naming ``owner.field``. Anything but a JSON
    object is left to the record's reader, which refuses it."""
    if not isinstance(raw, dict):
        return
    record = raw.get("type") or DEFAULT_TEST_TYPE
    for (name, field), why in REQUIRED_GIVEN.items():
        if name == record and field not in raw:
            raise MissingField(_at(owner, field), why=why)
    if record == DEFAULT_TEST_TYPE and raw.get("preset") is None and "pair_law" not in raw:
        raise MissingField(owner or record, limit=PRESET_OR_PAIR_LAW, why=PRESET_OR_PAIR_LAW_WHY)


def check_study_json(body, owner: str = "") -> None:
    """A study as a user gives it in JSON: its reference given
    (:data:`REQUIRED_GIVEN`) and that test checked by :func:`check_test_json`. Raises
    :class:`engine.core.errors.MissingField` naming the field (under ``owner``, the study's
    path in the request). Anything but a JSON object is left to
    :meth:`engine.StudySpec.from_dict`."""
    if not isinstance(body, dict):
        return
    if "reference" not in body:
        raise MissingField(_at(owner, "reference"), why=REQUIRED_GIVEN[("StudySpec", "reference")])
    check_test_json(body["reference"], _at(owner, "reference"))


def check_design(runs: int, waves: int, wave_runs: int, owner: str = "calibrate") -> None:
    """A calibration's design against :data:`DESIGN_MINIMUM`: ``runs`` design runs,
    ``waves`` history-matching waves of ``wave_runs`` runs each, whole numbers. Raises
    :class:`engine.ParameterError` naming ``owner.runs`` (``.waves``, ``.wave_runs``) and
    its limit."""
    for name, value in (("runs", runs), ("waves", waves), ("wave_runs", wave_runs)):
        low = DESIGN_MINIMUM[name]
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ParameterError(_at(owner, name), value, f"a whole number >= {low}")
