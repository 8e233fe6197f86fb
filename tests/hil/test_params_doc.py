"""The parameter reference in docs/ is generated from the declarations and kept current."""

from firmware.platform.params import markdown_reference
from hil.params_doc import REFERENCE, all_param_defs


def test_reference_is_current():
    want = markdown_reference(all_param_defs())
    assert REFERENCE.read_text() == want, (
        "docs/parameter_reference.md is out of date: run `hil params --out "
        "docs/parameter_reference.md`")


def test_every_parameter_has_a_description_and_group():
    for d in all_param_defs():
        assert d.short, f"{d.name} has no short description"
        assert d.group, f"{d.name} has no group"
