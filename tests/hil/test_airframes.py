"""``hil airframes`` and ``--airframe NAME|ID``: every airframe file of the ROMFS is flyable
from the host, named as a user would name it, and a wrong name is one clear line."""

import json

import pytest

from firmware import romfs
from hil import cli
from hil.airframes import HOST, all_airframes, resolve
from hil.missions import MISSIONS


def test_every_airframe_file_has_a_host_entry_and_a_mission():
    files = set(romfs.airframes())
    assert files == set(HOST), "an airframe file without host data, or host data without a file"
    for frame in all_airframes():
        assert frame.vehicle_class in ("multicopter", "fixedwing", "vtol")
        assert frame.vehicle_class in MISSIONS


def test_airframes_json_lists_id_name_and_class(capsys):
    assert cli.main(["airframes", "--json"]) == 0
    frames = json.loads(capsys.readouterr().out)
    by_id = {f["id"]: f for f in frames}
    assert by_id[4011]["class"] == "multicopter" and by_id[4011]["name"] == "dji_f450"
    assert by_id[2100]["class"] == "fixedwing" and by_id[2100]["name"] == "standard_plane"
    assert by_id[2100]["outputs"]["MAIN3"] == "throttle"
    assert cli.main(["airframes"]) == 0
    table = capsys.readouterr().out
    assert "standard_plane" in table and "fixedwing" in table


@pytest.mark.parametrize("key, want", [(2100, 2100), ("2100", 2100), ("plane", 2100),
                                       ("Standard_Plane", 2100), ("2100_standard_plane", 2100),
                                       ("standard plane", 2100), ("f450", 4011),
                                       ("4001", 4001)])
def test_resolve_by_id_name_title_or_alias(key, want):
    assert resolve(key).id == want


def test_an_unknown_airframe_is_one_line_and_exit_2(capsys):
    assert cli.main(["run", "--airframe", "zeppelin"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown airframe 'zeppelin'" in err[0] and "2100" in err[0]
    assert cli.main(["fly", "--airframe", "9999"]) == 2


def test_each_airframe_files_outputs_are_what_its_world_model_drives():
    """The airframe file's ``@output MAIN3 throttle`` lines and the world's channel map say the
    same: a motor channel is a motor or throttle, a servo channel names its surface."""
    from hil.world.fdm import AIRFRAMES, N_MAIN, Motor, Servo

    for frame in all_airframes():
        outputs = dict(frame.outputs)
        model = AIRFRAMES[frame.host.world_model]
        for ch, out in enumerate(model.outputs):
            name = f"MAIN{ch + 1}" if ch < N_MAIN else f"AUX{ch - N_MAIN + 1}"
            said = outputs.get(name, "")
            if isinstance(out, Motor):
                assert said.startswith(("motor", "throttle")), (frame.name, name, said)
            elif isinstance(out, Servo):
                surface = out.prop.split("/")[1].split("-")[0]   # fcs/aileron-cmd-norm
                assert said == surface, (frame.name, name, said, out.prop)
            else:
                assert not said, (frame.name, name, said)
