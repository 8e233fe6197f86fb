"""RC faults: the radio link between the pilot's transmitter and the receiver on the IO.

They act on the orchestrator's RC rig (:mod:`hil.rc`): the transmitter's power and the
receivers' link windows. What reaches the IO's RC input is then whatever the receiver model
puts on the wire in that situation, protocol by protocol:

* S.BUS (Futaba, FrSky): frames keep coming every 7/14 ms with the *frame lost* flag and the
  last good values; after the receiver's failsafe delay the *failsafe* bit is set too and the
  channels go to the bound failsafe preset (or hold, or stop).
* DSM (Spektrum satellites): there is no flag; the satellite simply stops sending, and the IO
  declares RC lost 200 ms after the last frame.
* PPM: the receiver repeats the last pulse train, then stops pulsing (or sends its preset).

The rig runs one quantum ahead of the boards (its script is fixed), so a fault takes effect
from the first RC frame that starts after the current quantum, at most one quantum late.

Target ``rc`` means every receiver on the rig; ``sbus``, ``dsm`` or ``ppm`` one receiver kind
(an error if the rig has none of that kind).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hil.faults import FaultError, fault_kind

RC_TARGETS = ("rc", "sbus", "dsm", "ppm")


def _receivers(rig: Any, target: str, kind: str) -> list[Any]:
    rc = rig.dev.get("rc")
    if rc is None:
        raise FaultError(f"fault {kind}: this rig has no RC receiver (SystemConfig rc=None)")
    rxs = [rx for rx in rc.receivers if target == "rc" or rx.kind == target]
    if not rxs:
        fitted = ", ".join(rx.kind for rx in rc.receivers) or "none"
        raise FaultError(f"fault {kind}: no {target} receiver on this rig (fitted: {fitted})")
    return rxs


def _open(windows: Any, t_ns: int, payload: Any = True) -> tuple:
    windows.add(t_ns, None, payload)
    return windows.items[-1]


def _close(windows: Any, item: tuple, t_ns: int) -> None:
    """End an open window at ``t_ns`` (the receivers keep their fault windows as a list)."""
    for i, it in enumerate(windows.items):
        if it is item:
            windows.items[i] = (item[0], max(t_ns, item[0]), item[2])
            return


def _window_kind(name: str, window: str, doc: str, targets: tuple[str, ...] = RC_TARGETS,
                 payload: Callable[[dict[str, Any]], Any] = lambda p: True,
                 **params: Any) -> None:
    """A kind that opens a fault window (the receiver attribute ``window``) on each targeted
    receiver at its start, with ``payload(params)``, and closes it at its stop."""

    def start(rig: Any, target: str, p: dict[str, Any], t_ns: int) -> list:
        value = payload(p)
        return [(rx, _open(getattr(rx, window), t_ns, value))
                for rx in _receivers(rig, target, name)]

    def stop(rig: Any, target: str, p: dict[str, Any], t_ns: int, token: list) -> None:
        for rx, item in token:
            _close(getattr(rx, window), item, t_ns)

    registered: Any = fault_kind(name, level="rc", doc=doc, targets=targets, **params)(start)
    registered.stopper(stop)


@fault_kind("rc.tx_off", level="rc", targets=("rc",),
            doc="The pilot's transmitter is switched off or its battery dies: every receiver "
                "bound to it loses the link at once and does what its protocol does on loss "
                "(S.BUS: frame-lost then failsafe flag; DSM: silence; PPM: hold, then no "
                "pulses). PX4 reports RC lost and, after COM_RC_LOSS_T, takes the NAV_RCL_ACT "
                "reaction (Return by default) once in the air.")
def tx_off_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _receivers(rig, target, "rc.tx_off")
    rig.dev["rc"].tx.power(t_ns, False)


@tx_off_start.stopper
def tx_off_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    rig.dev["rc"].tx.power(t_ns, True)


_window_kind("rc.out_of_range", "_out_of_range",
             "The receiver loses the RF link with the transmitter still on: out of range, "
             "a shadowed antenna, 2.4 GHz interference. The receiver behaves as on any link "
             "loss (see the module doc), and recovers when the link comes back.")
_window_kind("rc.sbus_failsafe", "_forced_failsafe",
             "An S.BUS receiver sets its failsafe flag with a good RF link (a receiver "
             "that decided on failsafe by itself, e.g. on low receiver voltage, or a "
             "failsafe test from the transmitter). The channels still carry values; the IO "
             "must treat the frame as RC lost, as PX4's S.BUS decoder does.",
             targets=("sbus",))


@fault_kind("rc.frame_loss", level="rc", targets=RC_TARGETS, prob=1.0,
            doc="A burst of lost RF frames (fading, a brief blockage): with ``prob`` 1 every "
                "frame in the window is lost, below 1 each frame is lost with that "
                "probability (seeded, reproducible). Short bursts are bridged by the "
                "receiver's hold and the IO's 200 ms RC timeout; PX4 must not fail safe for "
                "them, only count them (S.BUS frame-lost flag, DSM fades).")
def loss_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> list:
    prob = float(params["prob"])
    if not 0.0 < prob <= 1.0:
        raise FaultError(f"fault rc_frame_loss: prob {prob} outside (0, 1]")
    token = []
    for rx in _receivers(rig, target, "rc.frame_loss"):
        if prob >= 1.0:
            token.append((rx, _open(rx._dropped, t_ns), None))
        else:
            token.append((rx, None, rx.frame_loss_prob))
            rx.frame_loss_prob = prob
    return token


@loss_start.stopper
def loss_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: list) -> None:
    for rx, item, old_prob in token:
        if item is not None:
            _close(rx._dropped, item, t_ns)
        else:
            rx.frame_loss_prob = old_prob


def _glitch_probs(p: dict[str, Any]) -> tuple[float, float]:
    bp, sp = float(p["byte_prob"]), float(p["spike_prob"])
    if not (0.0 <= bp <= 1.0 and 0.0 <= sp <= 1.0):
        raise FaultError(f"fault rc.glitch: probabilities must be in [0, 1], got {bp}, {sp}")
    return (bp, sp)


_window_kind("rc.glitch", "_glitch",
             "Corruption on the receiver's wire or in its decoded channels (EMI on the "
             "signal lead, a marginal receiver): per frame, with ``byte_prob`` one byte "
             "(PPM: one spurious edge pair) is damaged, with ``spike_prob`` one channel "
             "jumps to a random value in a well-formed frame. The IO's decoder must reject "
             "damaged frames (parity, framing, sync) without declaring RC lost for a few "
             "bad ones.", payload=_glitch_probs, byte_prob=0.2, spike_prob=0.0)


#: receivers that can be plugged into another's connector: UART protocols on UART inputs
_UART_KINDS = ("sbus", "dsm")


@fault_kind("rc.wrong_protocol", level="rc", targets=_UART_KINDS, protocol="dsm",
            doc="The IO's RC input gets a receiver of another protocol than the one it "
                "listens for there (target: the fitted receiver, sbus or dsm; protocol: the "
                "receiver plugged in instead, bound to the same transmitter): a Spektrum "
                "satellite's 115200 8N1 bytes on the S.BUS input (100 kbit/s 8E2 behind its "
                "inverter), or an S.BUS receiver on the satellite port. The E14 IO firmware "
                "does not autodetect: each input has its own decoder, so the wrong line format "
                "gives framing/parity errors and bytes that never form a frame. Nothing valid "
                "is decoded: 200 ms after the last good frame the IO clears RC_OK and its "
                "source flag and raises ALARM_RC_LOST, the FMU sees input_rc rc_lost with no "
                "channels and, after COM_RC_LOSS_T, manual control lost. Swapping the right "
                "receiver back (it powers up and re-binds) restores RC.")
def wrong_protocol_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> list:
    from hil.rc import make_receiver

    proto = params["protocol"]
    if proto not in _UART_KINDS:
        raise FaultError(f"fault rc.wrong_protocol: protocol must be one of "
                         f"{', '.join(_UART_KINDS)} (a PPM pulse train on a UART input is not "
                         f"modelled), got {proto!r}")
    if proto == target:
        raise FaultError(f"fault rc.wrong_protocol: protocol {proto!r} is what the {target} "
                         f"input expects; give another one")
    rig_rc = rig.dev["rc"]
    token = []
    for rx in _receivers(rig, target, "rc.wrong_protocol"):
        wrong = make_receiver(proto, rig_rc.tx, port=rx.port, start_ns=t_ns, seed=rx.seed)
        rx._out = [r for r in rx._out if r[1] < t_ns]  # frames not yet on the wire: none
        item = _open(rx._unplugged, t_ns)
        rig_rc.receivers.append(wrong)
        token.append((rx, item, wrong))
    return token


@wrong_protocol_start.stopper
def wrong_protocol_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int,
                        token: list) -> None:
    rig_rc = rig.dev["rc"]
    for rx, item, wrong in token:
        wrong.unplug(t_ns)
        wrong._out = [r for r in wrong._out if r[1] < t_ns]
        if not wrong._out and wrong in rig_rc.receivers:
            rig_rc.receivers.remove(wrong)
        _close(rx._unplugged, item, t_ns)
