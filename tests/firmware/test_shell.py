"""The nsh-like shell: language, built-ins, param/uorb/listener/top/perf commands, errors."""

import pytest

from firmware.platform.params import MemoryPartition, ParamStorage
from firmware.shell import Shell
from firmware.shell.parser import ShellSyntaxError, tokenize
from tests.firmware.test_module import make_system


class Console:
    """A shell with its output collected; ``run(line)`` returns (status, text of that line)."""

    def __init__(self, system):
        self.system = system
        self.chunks = []
        self.sh = Shell(system, self.chunks.append)

    def run(self, line):
        self.chunks.clear()
        status = self.sh.execute(line)
        return status, "".join(self.chunks)

    def script(self, text, args=()):
        self.chunks.clear()
        status = self.sh.run_script(text, args, name="test.sh")
        return status, "".join(self.chunks)


@pytest.fixture
def con(platform, tmp_path):
    return Console(make_system(platform, tmp_path, reboot=lambda b: reboots.append(b)))


reboots: list = []


# -- language ------------------------------------------------------------------------------------

def test_unknown_command_then_next_command_runs(con):
    assert con.run("frobnicate now") == (127, "nsh: frobnicate: command not found\n")
    assert con.run("echo still here") == (0, "still here\n")
    assert con.run("echo $?") == (0, "0\n")
    con.run("false")
    assert con.run("echo $?")[1] == "1\n"


def test_variables_quotes_comments(con):
    con.run("set GREETING hello world")
    assert con.run('echo "$GREETING" \'$GREETING\' ${GREETING}x # comment')[1] == \
        "hello world $GREETING hello worldx\n"
    con.run("NAME=quad")
    assert con.run("echo ${NAME}_x.main.mix")[1] == "quad_x.main.mix\n"
    con.run("unset NAME")
    assert con.run("echo [$NAME]")[1] == "[]\n"
    assert con.run('echo "a\\"b" a\\ b')[1] == 'a"b a b\n'
    assert con.run("set")[1] == "GREETING=hello world\n"
    status, text = con.run('echo "open')
    assert status == 1 and "syntax error: unterminated \" quote" in text
    with pytest.raises(ShellSyntaxError):
        tokenize("echo 'x")


def test_test_command(con):
    (con.system.sd_root / "etc").mkdir()
    (con.system.sd_root / "etc" / "extras.txt").write_text("echo hi\n")
    cases = {"[ a = a ]": 0, "[ a != a ]": 1, "[ a == b ]": 1, "[ -f /fs/microsd/etc/extras.txt ]": 0,
             "[ -f /fs/microsd/nope ]": 1, "[ -d /fs/microsd/etc ]": 0, "[ -f /etc/init.d/rcS ]": 0,
             "[ -f /proc/x ]": 1, "[ 3 -gt 2 ]": 0, "[ 3 -le 2 ]": 1, "[ ! a = b ]": 0,
             "[ -z '' ]": 0, "[ -n '' ]": 1, "[ a = a -a b = c ]": 1, "[ a = b -o b = b ]": 0,
             "test x": 0, "[ ]": 1}
    for line, want in cases.items():
        assert con.run(line)[0] == want, line
    assert con.run("[ a = a") == (2, "[: missing ']'\n")
    status, text = con.run("[ x -gt 2 ]")
    assert status == 2 and "integer expected" in text
    assert con.run("[ a -zz b ]")[1] == "[: unknown operator '-zz'\n"


def test_if_then_else_nested_and_operators(con):
    _, text = con.script("""
set X yes
if [ $X = yes ]
then
    echo one
    if [ $X = no ]; then echo two; else echo three; fi
else
    echo four
    if [ 1 = 1 ]
    then
        echo never
    fi
fi
! false && echo negated
false || echo fallback
true && false && echo skipped
if ! [ $X = yes ]; then echo wrong; else echo right; fi
""")
    assert text == "one\nthree\nnegated\nfallback\nright\n"


def test_interactive_if_spans_lines(con):
    con.run("if [ 1 = 1 ]")
    assert con.run("then")[1] == ""
    assert con.run("echo inside")[1] == "inside\n"
    con.run("fi")
    assert con.run("echo after")[1] == "after\n"


def test_script_errors_have_line_numbers_and_script_goes_on(con):
    status, text = con.script("echo start\nbogus_cmd\nparam get NOPE\nfi\nidle start -x\n"
                              "if true\necho no then\nthen\necho end\n")
    lines = text.splitlines()
    assert lines[0] == "start"
    assert lines[1] == "test.sh:2: nsh: bogus_cmd: command not found"
    assert lines[2] == "test.sh:3: param get: parameter NOPE not found"
    assert lines[3] == "test.sh:4: nsh: syntax error: unexpected 'fi'"
    assert lines[4] == "test.sh:5: idle: bad options -x"
    assert "test.sh:7: nsh: syntax error: expected 'then' after the 'if' on line 6" in lines
    assert "test.sh:6: nsh: 'if' without a matching 'fi'" in lines
    assert status == 1


def test_sh_args_exit_and_missing_files(con):
    sd = con.system.sd_root
    (sd / "s.sh").write_text("echo $0 $1 $2 $#\nexit 3\necho unreachable\n")
    status, text = con.run("sh /fs/microsd/s.sh a b")
    assert (status, text) == (3, "/fs/microsd/s.sh a b 2\n")
    assert con.run("sh s.sh")[0] == 3          # relative to the SD card
    status, text = con.run("sh /fs/microsd/none.sh")
    assert (status, text) == (1, "sh: /fs/microsd/none.sh: No such file or directory\n")
    status, text = con.run("sh /usr/bin/x")
    assert status == 1 and "no such file or directory" in text
    (sd / "loop.sh").write_text("sh /fs/microsd/loop.sh\n")
    status, text = con.run("sh /fs/microsd/loop.sh")
    assert status == 1 and "nested more than 16 deep" in text
    assert con.run("exit 5")[0] == 5 and con.sh.exited
    assert con.run("exit -1")[0] == 255 and con.run("exit 300")[0] == 44   # 8 bits, as sh
    assert con.run("exit x")[1] == "exit: numeric argument required, got 'x'\n"


def test_internal_errors_never_escape(con):
    def boom(sh, argv):
        raise ZeroDivisionError("oops")

    from firmware.shell import Command
    con.sh.commands["boom"] = Command(boom, "raises")
    assert con.run("boom") == (1, "boom: internal error: ZeroDivisionError: oops\n")
    assert con.run("echo ok")[1] == "ok\n"

    def deep(sh, argv):
        return deep(sh, argv)

    con.sh.commands["deep"] = Command(deep, "recurses")
    assert con.run("deep; echo after") == (0, "deep: nesting too deep (Python recursion limit)\n"
                                              "after\n")


def test_an_interpreter_failure_drops_the_line_and_the_open_blocks(con, monkeypatch):
    assert con.run("if true") == (0, "") and con.sh.open_ifs == 1

    def broken(name):
        raise KeyError(name)

    monkeypatch.setattr(con.sh, "lookup", broken)
    status, text = con.run("then; echo $X; echo never")
    assert (status, text) == (1, "nsh: internal error: KeyError: 'X'\n")
    assert con.sh.open_ifs == 0
    monkeypatch.undo()
    status, text = con.script("if true\nthen\necho $X\necho never\nfi\n")
    assert (status, text) == (0, "\nnever\n")
    monkeypatch.setattr(con.sh, "lookup", broken)
    status, text = con.script("if true\nthen\necho $X\necho never\nfi\n")
    assert (status, text) == (1, "test.sh:3: nsh: internal error: KeyError: 'X'\n")


# -- system commands -----------------------------------------------------------------------------

def test_help_ver_reboot_dmesg_free_ls_cat(con):
    text = con.run("help")[1]
    assert "param" in text and "listener" in text and "blinker" in text
    assert con.run("help ver")[1].startswith("ver: ")
    assert con.run("help nothing")[0] == 1
    assert con.run("ver hw")[1] == "HW arch: PX4_FMU_V2\n"
    for name in ("PX4_FMU_V2", "PX4FMU_V2", "px4_fmu-v2"):
        assert con.run(f"ver hwcmp {name}")[0] == 0
    assert con.run("ver hwcmp PX4_FMU_V5 PX4_FMU_V2")[0] == 0
    assert con.run("ver hwcmp PX4_FMU_V5")[0] == 1
    assert "FW version" in con.run("ver all")[1]
    assert con.run("ver git")[1] == "FW git-hash: not provided by the build\n"
    status, text = con.run("ver banana")
    assert status == 1 and "ver: unknown argument 'banana'" in text and "usage: ver" in text
    assert con.run("ver")[0] == 1
    reboots.clear()
    assert con.run("reboot -b")[0] == 0 and reboots == [True]
    assert con.run("reboot -x")[0] == 1 and reboots == [True]
    con.system.platform.info("test", "hello dmesg")
    assert "INFO [test] hello dmesg" in con.run("dmesg")[1]
    assert con.run("dmesg -x")[0] == 1
    text = con.run("free")[1]
    n_params = len(con.system.params.names)       # the system parameters the console has
    assert "N/A in emulation" in text and f"parameters: {n_params} " in text
    assert con.run("free -h")[0] == 1
    assert "rcS" in con.run("ls /etc/init.d")[1]
    assert "@name DJI Flame Wheel F450" in con.run("cat /etc/init.d/airframes/4011_dji_f450")[1]
    assert con.run("cat /fs/microsd/none")[0] == 1


def test_reboot_without_callback(platform):
    c = Console(make_system(platform))
    status, text = c.run("reboot")
    assert status == 1 and "no reboot callback" in text


def test_ps_top_work_queue_perf(con):
    kernel = con.system.platform.kernel
    assert con.run("blinker start")[0] == 0
    kernel.run(1_000_000_000)                         # 1 s: 100 runs of 1 ms modelled CPU
    text = con.run("ps")[1]
    assert "blinker" in text and "wq:lp_default" in text and "every 10000 us" in text
    text = con.run("top")[1]
    row = next(line for line in text.splitlines() if line.strip().startswith("blinker"))
    assert row.split() == ["blinker", "100", "100.0", "100000.0", "10.00"]
    assert "total modelled load: 10.00 %" in text
    assert "host time: not measured" in text
    kernel.run(1_500_000_000)                         # the next top covers only 0.5 s
    text = con.run("top once")[1]
    assert "interval 0.500000 s" in text
    row = next(line for line in text.splitlines() if line.strip().startswith("blinker"))
    assert row.split()[1:3] == ["50", "100.0"]
    assert con.run("top now")[0] == 1
    text = con.run("work_queue status")[1]
    assert "wq:lp_default" in text and "|__ blinker" in text and "runs      150" in text
    assert con.run("work_queue")[0] == 1
    assert con.run("work_queue start")[0] == 1
    assert "blinker: cycles: 150 events" in con.run("perf")[1]
    assert con.run("perf reset")[0] == 0
    assert "blinker: cycles: 0 events" in con.run("perf")[1]
    assert con.run("perf latency")[0] == 1
    assert con.run("blinker hello")[1] == "hello from blinker\n"
    assert con.run("blinker stop")[0] == 0
    assert con.run("blinker status") == (1, "blinker: not running\n")


def test_top_host_share_with_an_injected_clock(platform):
    ticks = iter(range(10_000))
    clock = lambda: next(ticks) * 0.001              # every read advances 1 ms
    c = Console(make_system(platform, host_clock=clock))
    c.run("blinker start")
    platform.kernel.run(100_000_000)
    text = c.run("top")[1]
    assert "HOST %" in text and "host time in work items" in text
    row = next(line for line in text.splitlines() if line.strip().startswith("blinker"))
    assert float(row.split()[-1]) > 0


def test_uorb_top_status_and_listener(con):
    kernel = con.system.platform.kernel
    status, text = con.run("listener ping_test")
    assert status == 1 and "never published" in text
    con.run("blinker start")
    kernel.run(2_000_000_000)
    text = con.run("uorb top")[1]
    row = next(line for line in text.splitlines() if line.startswith("ping_test"))
    assert row.split() == ["ping_test", "0", "200", "100.0", "0", "1"]
    kernel.run(2_500_000_000)
    row = next(line for line in con.run("uorb top")[1].splitlines()
               if line.startswith("ping_test"))
    assert row.split()[2:4] == ["250", "100.0"]
    assert "ping_test" in con.run("uorb status")[1]
    assert con.run("uorb")[0] == 1 and con.run("uorb banana")[0] == 1
    status, text = con.run("listener ping_test")
    assert status == 0
    assert "TOPIC: ping_test instance 0 #250" in text
    assert "    seq: 250\n" in text and "    value: 125.0000\n" in text
    assert "    timestamp: 2500000 (0.000 ms ago)" in text
    status, text = con.run("listener ping_test -n 3 -i 0")
    assert status == 0 and "(1 of 3 messages" in text
    assert con.run("listener nosuch") == (1, "listener: unknown topic 'nosuch'\n")
    assert con.run("listener ping_test -n")[0] == 1
    assert con.run("listener ping_test -n x")[0] == 1
    assert con.run("listener ping_test -i 9")[0] == 1
    assert con.run("listener")[0] == 1


def test_listener_queued_topic_prints_stored_messages(con):
    p = con.system.platform
    for i in range(3):
        p.info("mod", f"message {i}")
    status, text = con.run("listener log_message -n 2")
    assert status == 0
    assert "text: '[mod] message 1'" in text and "text: '[mod] message 2'" in text
    assert "message 0" not in text


# -- param -----------------------------------------------------------------------------------------

def test_param_set_get_compare_greater(con):
    assert con.run("param set SYS_AUTOSTART 4001") == (0, "SYS_AUTOSTART: curr: 0 -> new: 4001\n")
    assert con.run("param get SYS_AUTOSTART") == (0, "4001\n")
    assert con.run("param compare SYS_AUTOSTART 4001")[0] == 0
    assert con.run("param compare SYS_AUTOSTART 10 4001")[0] == 0
    assert con.run("param compare SYS_AUTOSTART 4002")[0] == 1
    assert con.run("param greater SYS_AUTOSTART 4000")[0] == 0
    assert con.run("param greater SYS_AUTOSTART 4001")[0] == 1
    assert con.run("if param compare SYS_AUTOSTART 4001; then echo quad; fi")[1] == "quad\n"
    status, text = con.run("param set SYS_AUTOSTART 1.5")
    assert status == 1 and "integer parameter" in text
    assert con.run("param set NOPE 1") == (1, "param set: parameter NOPE not found\n")
    assert con.run("param compare NOPE 1")[0] == 1
    assert con.run("param compare SYS_AUTOSTART abc")[0] == 1
    assert con.run("param get")[0] == 1
    assert con.run("param frob")[0] == 1
    assert con.run("param")[0] == 1
    text = con.run("param set SYS_AUTOCONFIG 5")[1]
    assert "outside its range" in text
    assert con.run("param reset SYS_AUTOCONFIG SYS_AUTOSTART")[0] == 0
    assert con.run("param get SYS_AUTOSTART")[1] == "0\n"
    assert con.run("param reset NOPE")[0] == 1


def test_param_show_changed_status_reset_all(con):
    con.run("param set SDLOG_MODE 1")
    text = con.run("param show SDLOG")[1]
    assert "* SDLOG_MODE [" in text and "  SDLOG_PROFILE [" in text
    assert f"4/{len(con.system.params.names)} parameters shown" in text
    text = con.run("param show -c")[1]
    assert "SDLOG_MODE" in text and "SYS_AUTOSTART" not in text and f"1/{len(con.system.params.names)}" in text
    assert con.run("param show -x")[0] == 1
    assert "storage: none" in con.run("param status")[1]
    assert con.run("param save")[0] == 1 and con.run("param load")[0] == 1
    assert con.run("param reset_all")[1] == "1 parameters reset to defaults\n"


def test_param_save_load_with_storage(platform, tmp_path):
    system = make_system(platform, tmp_path)
    system.params.storage = ParamStorage(MemoryPartition(8192))
    c = Console(system)
    c.run("param set SYS_AUTOSTART 4011")
    assert c.run("param save")[0] == 0
    c.run("param set SYS_AUTOSTART 1")
    assert c.run("param load")[0] == 0
    assert c.run("param get SYS_AUTOSTART")[1] == "4011\n"
    assert "last save #1" in c.run("param status")[1]


def test_param_export_import_round_trip(con):
    con.run("param set SYS_AUTOSTART 4011")
    con.run("param set BLINK_RATE 250")
    assert con.run("param export backup.params")[0] == 0
    assert "\tSYS_AUTOSTART\t4011\t6" in (con.system.sd_root / "backup.params").read_text()
    con.run("param reset_all")
    assert con.run("param import /fs/microsd/backup.params") == \
        (0, f"imported {len(con.system.params.names)} parameters from /fs/microsd/backup.params\n")
    assert con.run("param get SYS_AUTOSTART")[1] == "4011\n"
    assert con.run("param get BLINK_RATE")[1] == "250\n"
    (con.system.sd_root / "bad.params").write_text("1\t1\tSYS_AUTOSTART\t7\t6\n1\t1\tNOPE\t1\t6\n")
    status, text = con.run("param import bad.params")
    assert status == 1 and "param import: bad.params: line 2: unknown parameter NOPE" in text
    assert con.run("param get SYS_AUTOSTART")[1] == "7\n"
    assert con.run("param import none.params")[0] == 1
    assert con.run("param export /etc/../../x")[0] == 1


def test_param_without_params_or_sd(platform):
    from firmware.system import System

    c = Console(System(platform))
    assert c.run("param show") == (1, "param: no parameters on this system\n")
    c2 = Console(make_system(platform))
    status, text = c2.run("param export x.params")
    assert status == 1 and "no SD card present" in text


def test_default_output_is_the_board_console(platform):
    seen = []
    system = make_system(platform, console=seen.append)
    sh = Shell(system)
    assert sh.execute("echo to the console") == 0
    assert sh.execute("blinker start") == 0 and sh.execute("blinker hello") == 0
    assert "".join(seen) == "to the console\nhello from blinker\n"
    quiet = make_system(platform)
    Shell(quiet).execute("echo kept")
    assert quiet.console_lines == ["kept"]


# -- limits and bad input (issue 18) -------------------------------------------------------------

CONSOLE = ("console", (57_600, 8, "N", 1, 0))


def _type_on_console(board, line, budget_ns=4_000_000_000):
    """Type ``line`` and Enter on the FMU's console UART; returns what the board sent back up
    to its next prompt (the echo included)."""
    t = board.kernel.now_ns
    records = [(CONSOLE[0], t, (*CONSOLE[1], line.encode() + b"\r"))]  # what a terminal sends
    out = bytearray()
    end = t + budget_ns
    while t < end and not out.endswith(b"nsh> "):
        t += 50_000_000
        for port, _t, payload in board.advance(t, records):
            if port == CONSOLE[0] and payload[5]:
                out += payload[5]
        records = []
    return out.decode("latin-1")


def test_a_deeply_nested_console_line_does_not_stop_the_board():
    # Issue 18, defect 2: this line recursed in the interpreter and the RecursionError stopped
    # the FMU's kernel (KernelError). Now it is refused and the board answers the next line.
    from fmu.board import FmuV2Board

    board = FmuV2Board(seed=1, sd_root=None)
    board.advance(1_500_000_000, [])
    reply = _type_on_console(board, "if true; " * 600 + "then fi " * 600)
    # The console's line buffer keeps 4 x 128 bytes, as readline's fixed buffer bounds it.
    assert "nsh: line too long (512 characters, at most 127)" in reply
    # What a terminal sends is UTF-8, and the shell gets the characters that were typed.
    reply = _type_on_console(board, "echo é").encode("latin-1")
    assert reply.endswith("é\nnsh> ".encode()), reply
    assert _type_on_console(board, "echo ok").endswith("echo ok\r\nok\nnsh> ")
    assert board.ctl_shell("echo $?") == (0, "0\n")
    # Backspace erases a whole character (both bytes of "é", not one: that left an invalid
    # byte the shell got as U+FFFD), and the terminal is told to erase it too.
    reply = _type_on_console(board, "echo aé\x7fb").encode("latin-1")
    assert reply.endswith("echo aé\x08 \x08b\r\nab\nnsh> ".encode()), reply


def test_if_nesting_is_bounded_as_nsh_bounds_it(con):
    assert con.run("if true;then " * 8 + "echo deep") == (0, "deep\n")
    assert con.run("fi;" * 8) == (0, "")
    status, text = con.run("if true;then " * 9 + "echo deep")
    assert (status, text) == (1, "nsh: if: nesting too deep (at most 8)\n")
    assert con.run("echo ok") == (0, "ok\n")          # the session is back at the top level
    assert con.run("fi")[0] == 1                        # no block left open
    status, text = con.script("if true\n" * 9 + "then\necho never\nfi\n" * 9 + "echo after\n")
    assert status == 1 and text == "test.sh:9: nsh: if: nesting too deep (at most 8)\n"


def test_overlong_lines_and_expansions_are_refused(con):
    status, text = con.run("echo " + "x" * 200)
    assert (status, text) == (1, "nsh: line too long (205 characters, at most 127)\n")
    con.run("set A " + "y" * 100)
    status, text = con.run("set B $A$A$A$A$A$A$A$A$A$A$A")
    assert (status, text) == (1, "nsh: set: argument too long (1100 characters, at most 1024)\n")
    con.run("set B $A $A $A $A $A $A")                      # 605 characters: stored
    con.run("set C $B $B")                                  # 1211: stored, but not expandable
    status, text = con.run("echo $C")
    assert (status, text) == (1, "nsh: echo: argument too long (1211 characters, at most 1024)\n")
    assert con.run("$C")[1] == "nsh: argument too long (1211 characters, at most 1024)\n"
    status, text = con.script("echo " + "z" * 130 + "\necho next\n")
    assert status == 1 and text == "test.sh:1: nsh: line too long (135 characters, at most 127)\n"
    assert con.run("echo ok") == (0, "ok\n")


def test_a_script_that_runs_itself_stops_at_the_depth_limit(con):
    (con.system.sd_root / "me.sh").write_text("echo $#\nsh me.sh x $1\n")
    status, text = con.run("sh me.sh")
    assert status == 1 and "sh: me.sh: scripts nested more than 16 deep" in text
    assert text.count("\n") == 17 and con.run("echo ok") == (0, "ok\n")


def test_binary_files_are_not_text(con):
    # Issue 18, defect 8: a binary file given to sh or param import was an "internal error:
    # UnicodeDecodeError"; it is a clear error naming the command, the path and the byte.
    sd = con.system.sd_root
    (sd / "bin.sh").write_bytes(b"echo hi\n\xff\xfe\x00garbage")
    (sd / "bin.params").write_bytes(b"1\t1\tSYS_AUTOSTART\t7\t6\n\x89PNG\r\n")
    status, text = con.run("sh bin.sh")
    assert (status, text) == (1, "sh: bin.sh: not a text file (invalid UTF-8 at byte 8)\n")
    status, text = con.run("param import bin.params")
    assert (status, text) == (1, "param import: bin.params: not a text file "
                                 "(invalid UTF-8 at byte 22)\n")
    assert con.run("param get SYS_AUTOSTART")[1] == "0\n"       # nothing half-imported
    status, text = con.run("cat /fs/microsd/bin.sh")
    assert (status, text) == (1, "cat: /fs/microsd/bin.sh: not a text file "
                                 "(invalid UTF-8 at byte 8)\n")
    host = sd / "bin.sh"
    status = con.sh.run_script(host)
    assert status == 1 and f"sh: {host}: not a text file" in "".join(con.chunks)
    assert con.run("echo ok") == (0, "ok\n")
