"""STM32 general-purpose timer (TIM2..TIM5 style, plus BDTR.MOE for TIM1/TIM8), register level.

Used for the IO's eight PWM outputs (TIM2/3/4), the FMU's AUX PWM (TIM1/TIM4) and PPM input
capture. Firmware uses :meth:`Timer.write` / :meth:`Timer.read` at the reference manual's offsets
(RM0090 / RM0041 "TIMx registers"); the world sees PWM through ``channel(n).on_pwm``.

No event per period. The counter is arithmetic: while counting, an *epoch* (anchor time,
counter value at the anchor, active PSC and ARR) gives

    ticks(t) = floor((t - t_anchor) * f_clk / ((PSC+1) * 10**9))     (exact integers)
    CNT(t)   = (CNT_anchor + ticks) wrapping to 0 after ARR (the first wrap after 2**bits - 1
               if CNT was above ARR)

The anchor is kept as ``t_anchor * f_clk`` so re-anchoring on a tick boundary stays exact
forever. The time of tick k is the first whole ns at which ``ticks(t) >= k``,
``t_anchor + ceil(k * (PSC+1) * 10**9 / f_clk)``: with a 1 MHz tick (the IO's PSC 23 at 24 MHz)
tick k is exactly ``t_anchor + k * 1000``; with a non-integer tick period the ceiling keeps an
event scheduled at tick k consistent with CNT read in that event.

Kernel events are scheduled only for something observable: the update event (UEV) at which
preloaded PSC / ARR (CR1.ARPE) / CCRx (CCMRx.OCxPE) become active, the update interrupt while
DIER.UIE is set, and compare matches of output channels while their CCxIE is set. SR.UIF is
computed lazily from the number of UEVs since it was last cleared.

Not modelled (logged when set): down/center-aligned counting (CR1.DIR/CMS), one-pulse mode,
UDIS, slave modes (SMCR), repetition counter (RCR), input filters, DMA; output-compare modes
other than PWM 1/2 and forced levels; CCxIF of output channels whose CCxIE is clear. The IRQ is
raised once when an enabled flag sets (NVIC pending bit), not re-raised while it stays set.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Final

from board.gpio import Pin
from board.kernel import PRIO_HW, PRIO_ISR, Event, Kernel, call_in_isr
from board.timer_regs import (
    REGISTERS, OFFSETS, CCR_INDEX, CR1_CEN, CR1_URS, CR1_ARPE, DIER_UIE, SR_UIF, EGR_UG, BDTR_MOE, OCM_FORCE_HIGH, OCM_PWM1, OCM_PWM2, UNMODELLED_CR1, cc_if, cc_of,
)

__all__ = ["REGISTERS", "PwmListener", "Timer", "TimerChannel", "TimerIrqHandler"]

log = logging.getLogger(__name__)

#: ``listener(t_ns, high_ns, period_ns)``: the output waveform from ``t_ns`` on. A constant
#: level is reported as ``high_ns`` 0 (low) or ``period_ns`` (high).
PwmListener = Callable[[int, int, int], None]
#: ``handler(timer, t_ns)``: the timer's IRQ handler, run in interrupt context.
TimerIrqHandler = Callable[["Timer", int], None]

class _Epoch:
    """Counter arithmetic between two re-anchorings (see module docstring)."""

    __slots__ = ("arr", "c0", "counting", "d", "f", "psc", "t0s", "top")

    def __init__(self, f: int, top: int, t0s: int, c0: int, psc: int, arr: int,
                 counting: bool) -> None:
        self.f, self.top, self.t0s, self.c0 = f, top, t0s, c0
        self.psc, self.arr, self.counting = psc, arr, counting
        self.d = (psc + 1) * 1_000_000_000

    def ticks(self, t: int) -> int:
        return (t * self.f - self.t0s) // self.d

    def tick_time(self, n: int) -> int:
        return -((-(self.t0s + n * self.d)) // self.f)

    def first_wrap(self) -> int:
        period = self.arr + 1
        return period - self.c0 if self.c0 < period else self.top + 1 - self.c0

    def cnt_at_tick(self, n: int) -> int:
        n1 = self.first_wrap()
        return self.c0 + n if n < n1 else (n - n1) % (self.arr + 1)

    def cnt(self, t: int) -> int:
        return self.cnt_at_tick(self.ticks(t)) if self.counting else self.c0

    def uevs_through(self, n: int) -> int:
        n1 = self.first_wrap()
        return 0 if n < n1 else 1 + (n - n1) // (self.arr + 1)

    def next_uev_after(self, n: int) -> int:
        n1 = self.first_wrap()
        return n1 if n < n1 else n1 + ((n - n1) // (self.arr + 1) + 1) * (self.arr + 1)

    def next_match_after(self, n: int, v: int) -> int | None:
        n1, period = self.first_wrap(), self.arr + 1
        best = None
        if self.c0 <= v and v - self.c0 < n1 and v - self.c0 > n:
            best = v - self.c0
        if v < period:
            m = n1 + v
            if m <= n:
                m += ((n - m) // period + 1) * period
            best = m if best is None else min(best, m)
        return best

    def rebase(self, t: int) -> int:
        """Move the anchor to the last tick boundary at or before ``t``; returns the UEVs
        passed on the way."""
        n = self.ticks(t)
        uevs, self.c0 = self.uevs_through(n), self.cnt_at_tick(n)
        self.t0s += n * self.d
        return uevs


class TimerChannel:
    """Capture/compare channel ``n`` (1-based) of a timer: PWM output or input capture."""

    def __init__(self, timer: Timer, n: int) -> None:
        self.timer, self.n = timer, n
        self._listeners: list[PwmListener] = []
        self.pin: Pin | None = None
        self._psc_count = 0  # edges seen towards the ICxPSC divider

    def on_pwm(self, listener: PwmListener) -> None:
        """Call ``listener(t_ns, high_ns, period_ns)`` whenever the output waveform changes."""
        if not callable(listener):
            raise TypeError(f"{self.timer.name} CH{self.n}: PWM listener {listener!r} not callable")
        self._listeners.append(listener)

    def remove_pwm_listener(self, listener: PwmListener) -> None:
        self._listeners.remove(listener)  # undo on_pwm

    @property
    def pulse_ns(self) -> int:
        """High time per period of the output now."""
        return self.timer._current_wave(self.n)[0]

    @property
    def period_ns(self) -> int:
        """Period of the output now ((ARR+1) * (PSC+1) / f_clk)."""
        return self.timer._current_wave(self.n)[1]

    def level_at(self, t_ns: int) -> int:
        """Output pin level at ``t_ns`` assuming no further register writes."""
        return self.timer._level_at(self.n, t_ns)

    def bind_input(self, pin: Pin) -> None:
        """Connect ``pin`` to this channel's TIx input (input capture when CCxS = 01)."""
        if not isinstance(pin, Pin):
            raise TypeError(f"{self.timer.name} CH{self.n}: bind_input needs a Pin, got {pin!r}")
        if self.pin is not None:
            self.pin.remove_listener(self._on_edge)
        self.pin = pin
        pin.on_change(self._on_edge)

    def _on_edge(self, pin: Pin, t_ns: int, level: int) -> None:
        self.timer._edge(self, t_ns, level)


class Timer:
    """One STM32 timer: counter, prescaler, auto-reload, ``channels`` capture/compare units."""

    def __init__(self, kernel: Kernel, name: str, clock_hz: int, channels: int = 4,
                 bits: int = 16, advanced: bool = False) -> None:
        """``advanced=True`` (TIM1/TIM8) gates outputs with BDTR.MOE."""
        if type(clock_hz) is not int or clock_hz <= 0:
            raise ValueError(f"timer {name}: clock_hz must be a positive int, got {clock_hz!r}")
        if bits not in (16, 32):
            raise ValueError(f"timer {name}: bits must be 16 or 32, got {bits!r}")
        if type(channels) is not int or not 0 <= channels <= 4:
            raise ValueError(f"timer {name}: channels must be 0..4, got {channels!r}")
        self.kernel, self.name, self.clock_hz = kernel, name, clock_hz
        self.bits, self.top, self.advanced = bits, (1 << bits) - 1, advanced
        self._ch = [TimerChannel(self, n) for n in range(1, channels + 1)]
        self._regs = {name: (self.top if reset is None else reset)
                      for name, reset in REGISTERS.values()}
        self._ccr_active = [0, 0, 0, 0]
        self._ep = _Epoch(clock_hz, self.top, 0, 0, 0, self.top, False)
        self._uev_base = self._uif_mark = 0  # UEVs before the anchor; at the last UIF clear
        self._uif_flag = self._irq_pending = self._ev_uev = False
        self._pend_t: int | None = None  # time of the UEV that will load pending preloads
        self._event: Event | None = None
        self._ev_cc: list[int] = []
        self._irq: TimerIrqHandler | None = None
        self._waves = [self._wave(ch.n) for ch in self._ch]
        self._logged: set[str] = set()

    # -- public register interface ----------------------------------------------------------

    def channel(self, n: int) -> TimerChannel:
        """Channel ``n``, 1-based like the reference manual (CH1..CH4)."""
        if type(n) is not int or not 1 <= n <= len(self._ch):
            raise ValueError(f"timer {self.name}: channel must be 1..{len(self._ch)}, got {n!r}")
        return self._ch[n - 1]

    def attach_irq(self, handler: TimerIrqHandler | None) -> None:
        """The timer's interrupt vector: ``handler(timer, t_ns)`` when an enabled flag sets."""
        self._irq = handler

    def write(self, offset: int, value: int) -> None:
        """Firmware store to the register at ``offset``."""
        name = self._reg_name(offset, "write")
        if type(value) is not int or not 0 <= value <= 0xFFFFFFFF:
            raise ValueError(f"timer {self.name}: write {name}: value must be a 32-bit int, "
                             f"got {value!r}")
        t = self.kernel.context_ns
        self._sync(t)
        if name in CCR_INDEX:  # the mixer rewrites CCRs up to 400 times a second
            i = CCR_INDEX[name]
            before = self._ccr_active[i]
            self._w_ccr(name, value, t)
            self._reschedule(t)
            if self._ccr_active[i] != before:  # else (preloaded: until the UEV) no wave changed
                self._notify(t)
            return
        getattr(self, "_w_" + name.lower(), self._w_plain)(name, value, t)
        self._reschedule(t)
        self._notify(t)

    def read(self, offset: int) -> int:
        """Firmware load from the register at ``offset`` (with the hardware's side effects)."""
        name = self._reg_name(offset, "read")
        t = self.kernel.context_ns
        if self._sync(t):
            self._reschedule(t)
        if name.startswith("CCR"):
            return self._r_ccr(int(name[3]), t)
        reader = getattr(self, "_r_" + name.lower(), None)
        return reader(t) if reader else self._regs[name]

    def write_reg(self, name: str, value: int) -> None:
        """:meth:`write` by register name ('ARR', 'CCR1', ...)."""
        self.write(self._offset(name), value)

    def read_reg(self, name: str) -> int:
        """:meth:`read` by register name."""
        return self.read(self._offset(name))

    def counter_at(self, t_ns: int) -> int:
        """CNT at ``t_ns`` assuming no further register writes (no side effects)."""
        return self._epoch_at(t_ns)[0].cnt(t_ns)

    def _reg_name(self, offset: int, where: str) -> str:
        entry = REGISTERS.get(offset) if type(offset) is int else None
        if entry is None:
            at = f"{offset:#04x}" if type(offset) is int else repr(offset)
            raise ValueError(f"timer {self.name}: {where} at offset {at}: no such register "
                             f"(0x00..0x44, word aligned)")
        return entry[0]

    def _offset(self, name: str) -> int:
        off = OFFSETS.get(name.upper()) if isinstance(name, str) else None
        if off is None:
            raise ValueError(f"timer {self.name}: no register named {name!r}")
        return off

    # -- register behaviour -----------------------------------------------------------------

    def _w_plain(self, name: str, value: int, t: int) -> None:
        self._regs[name] = value & 0xFFFF
        if value and name in ("CR2", "SMCR", "RCR"):
            self._log_once(name, f"{name} = {value:#x} is stored but not modelled")

    def _w_cr1(self, name: str, value: int, t: int) -> None:
        old = self._regs["CR1"]
        self._regs["CR1"] = value & 0x3FF
        if value & UNMODELLED_CR1:
            self._log_once("CR1", f"CR1 = {value:#x}: DIR/CMS/OPM/UDIS are not modelled")
        if not value & CR1_ARPE and self._ep.arr != self._regs["ARR"]:
            self._set_arr_now(self._regs["ARR"], t)  # an unbuffered ARR is the preload
        if (value ^ old) & CR1_CEN:
            self._set_counting(t)

    def _w_dier(self, name: str, value: int, t: int) -> None:
        self._regs["DIER"] = value & 0x5F5F
        if self._r_sr(t) & value & 0x1F:
            self._raise_irq(t)  # enabling an interrupt whose flag is already set fires it

    def _r_sr(self, t: int) -> int:
        sr = self._regs["SR"]
        if self._uif_flag or self._global_uevs(t) > self._uif_mark:
            sr |= SR_UIF
        return sr

    def _w_sr(self, name: str, value: int, t: int) -> None:
        # rc_w0: writing 0 clears a flag, writing 1 leaves it.
        self._regs["SR"] &= value | SR_UIF
        if not value & SR_UIF:
            self._uif_flag = False
            self._uif_mark = self._global_uevs(t)

    def _w_egr(self, name: str, value: int, t: int) -> None:
        if value & EGR_UG:
            self._update_generation(t)
        for ch in self._ch:
            if value & cc_if(ch.n):
                if self._is_input(ch.n):
                    self._capture(ch.n, t)
                else:
                    self._set_cc_flag(ch.n, t)

    def _w_ccmr1(self, name: str, value: int, t: int) -> None:
        self._regs[name] = value & 0xFFFF
        for ch in self._ch:
            if not self._is_input(ch.n) and not self._oc_preload(ch.n):
                self._ccr_active[ch.n - 1] = self._regs[f"CCR{ch.n}"]

    def _w_ccmr2(self, name: str, value: int, t: int) -> None:
        self._w_ccmr1(name, value, t)

    def _w_cnt(self, name: str, value: int, t: int) -> None:
        if self._ep.counting:
            self._uev_base += self._ep.rebase(t)
        self._ep.c0 = value & self.top

    def _r_cnt(self, t: int) -> int:
        return self._ep.cnt(t)

    def _w_psc(self, name: str, value: int, t: int) -> None:
        self._regs["PSC"] = value & 0xFFFF  # always preloaded: active at the next UEV

    def _w_arr(self, name: str, value: int, t: int) -> None:
        self._regs["ARR"] = value & self.top
        if not self._regs["CR1"] & CR1_ARPE:
            self._set_arr_now(value & self.top, t)

    def _w_ccr(self, name: str, value: int, t: int) -> None:
        n = int(name[3])
        if n > len(self._ch) or self._is_input(n):
            return  # capture registers are read-only in input mode
        self._regs[name] = value & self.top
        if not self._oc_preload(n):
            self._ccr_active[n - 1] = value & self.top

    def _r_ccr(self, n: int, t: int) -> int:
        if n <= len(self._ch) and self._is_input(n):
            self._regs["SR"] &= ~cc_if(n)  # reading a capture clears CCxIF
        return self._regs[f"CCR{n}"]

    def _ccmr_bits(self, n: int) -> int:
        reg = self._regs["CCMR1" if n <= 2 else "CCMR2"]
        return (reg >> (8 if n % 2 == 0 else 0)) & 0xFF

    def _is_input(self, n: int) -> bool:
        return self._ccmr_bits(n) & 3 != 0

    def _oc_preload(self, n: int) -> bool:
        return bool(self._ccmr_bits(n) & 0x08)

    def _ccer_bits(self, n: int) -> int:
        return (self._regs["CCER"] >> (4 * (n - 1))) & 0xF

    # -- counter state changes --------------------------------------------------------------

    def _set_counting(self, t: int) -> None:
        ep = self._ep
        run = bool(self._regs["CR1"] & CR1_CEN) and ep.arr > 0  # ARR = 0 blocks the counter
        if run == ep.counting:
            return
        if ep.counting:
            self._uev_base += ep.rebase(t)
        else:
            ep.t0s = t * self.clock_hz
        ep.counting = run

    def _set_arr_now(self, arr: int, t: int) -> None:
        ep = self._ep
        if ep.counting:
            self._uev_base += ep.rebase(t)
        ep.arr = arr
        self._set_counting(t)

    def _load_shadows(self, ep: _Epoch, ccr: list[int]) -> None:
        ep.psc = self._regs["PSC"]
        ep.d = (ep.psc + 1) * 1_000_000_000
        ep.arr = self._regs["ARR"]
        for ch in self._ch:
            if not self._is_input(ch.n):
                ccr[ch.n - 1] = self._regs[f"CCR{ch.n}"]

    def _pending(self) -> bool:
        ep, regs = self._ep, self._regs
        if regs["PSC"] != ep.psc or regs["ARR"] != ep.arr:
            return True
        return any(not self._is_input(ch.n) and regs[f"CCR{ch.n}"] != self._ccr_active[ch.n - 1]
                   for ch in self._ch)

    def _update_generation(self, t: int) -> None:
        """EGR.UG: reload shadows, clear the counter and the prescaler, flag UIF (URS = 0)."""
        ep = self._ep
        if ep.counting:
            self._uev_base += ep.rebase(t)
        self._load_shadows(ep, self._ccr_active)
        ep.c0, ep.t0s, ep.counting = 0, t * self.clock_hz, False
        self._pend_t = None
        self._set_counting(t)
        if not self._regs["CR1"] & CR1_URS:
            self._uif_flag = True
            if self._regs["DIER"] & DIER_UIE:
                self._raise_irq(t)

    def _uev_epoch(self, ep: _Epoch, t_uev: int) -> tuple[_Epoch, list[int], int]:
        """The epoch after the pending UEV at ``t_uev``, its CCRs and the UEVs passed."""
        n = ep.ticks(t_uev)
        new = _Epoch(self.clock_hz, self.top, ep.t0s + n * ep.d, 0, ep.psc, ep.arr, True)
        ccr = list(self._ccr_active)
        self._load_shadows(new, ccr)
        new.counting = new.arr > 0  # ARR = 0 blocks the counter
        return new, ccr, ep.uevs_through(n)

    def _epoch_at(self, t: int) -> tuple[_Epoch, list[int]]:
        if self._pend_t is not None and self._pend_t <= t:
            return self._uev_epoch(self._ep, self._pend_t)[:2]
        return self._ep, self._ccr_active

    def _sync(self, t: int) -> bool:
        """Apply a pending UEV that happened at or before ``t``; True if one did."""
        t_uev = self._pend_t
        if t_uev is None or t_uev > t:
            return False
        self._ep, self._ccr_active, uevs = self._uev_epoch(self._ep, t_uev)
        self._uev_base += uevs
        self._pend_t = None
        self._notify(t_uev)
        return True

    def _global_uevs(self, t: int) -> int:
        ep = self._ep
        return self._uev_base + (ep.uevs_through(ep.ticks(t)) if ep.counting else 0)

    # -- events -----------------------------------------------------------------------------

    def _reschedule(self, t: int) -> None:
        """Schedule the next observable event after ``t`` (or none)."""
        Kernel.cancel(self._event)
        ep, self._event, self._pend_t = self._ep, None, None
        if not ep.counting:
            return
        n = ep.ticks(t)
        best: int | None = None
        uev = False
        dier = self._regs["DIER"]
        if self._pending() or dier & DIER_UIE:
            best = ep.next_uev_after(n)
            uev = True
            if self._pending():
                self._pend_t = ep.tick_time(best)
        cc: list[int] = []
        for ch in self._ch:
            if dier & cc_if(ch.n) and not self._is_input(ch.n):
                m = ep.next_match_after(n, self._ccr_active[ch.n - 1])
                if m is None or (best is not None and m > best):
                    continue
                if best is None or m < best:
                    best, uev, cc = m, False, []
                cc.append(ch.n)
        if best is None:
            return
        self._ev_uev, self._ev_cc = uev, cc
        self._event = self.kernel.call_at(ep.tick_time(best), self._on_event, priority=PRIO_HW)

    def _on_event(self) -> None:
        t = self.kernel.now_ns
        self._event = None
        self._sync(t)
        if self._ev_uev and self._regs["DIER"] & DIER_UIE:
            self._raise_irq(t)
        for n in self._ev_cc:
            self._set_cc_flag(n, t)
        self._reschedule(t)

    def _set_cc_flag(self, n: int, t: int) -> None:
        self._regs["SR"] |= cc_if(n)
        if self._regs["DIER"] & cc_if(n):
            self._raise_irq(t)

    def _raise_irq(self, t: int) -> None:
        if self._irq is None or self._irq_pending:
            return
        self._irq_pending = True
        self.kernel.call_at(t, self._fire_irq, t, priority=PRIO_ISR)

    def _fire_irq(self, t: int) -> None:
        self._irq_pending = False
        if self._irq is not None:
            call_in_isr(self.kernel, self._irq, self, t)

    # -- input capture ----------------------------------------------------------------------

    def _edge(self, ch: TimerChannel, t: int, level: int) -> None:
        n = ch.n
        if not self._is_input(n):
            return
        ccer = self._ccer_bits(n)
        if not ccer & 1:
            return  # CCxE: capture disabled
        pol = ccer & 0b1010  # CCxP (bit 1), CCxNP (bit 3)
        want = level == 1 if pol == 0 else (level == 0 if pol == 0b0010 else True)
        if pol == 0b1000:
            want = level == 1  # CCxP=0, CCxNP=1 is reserved; behave as rising
        if not want:
            return
        psc = (self._ccmr_bits(n) >> 2) & 3  # ICxPSC: capture every 1, 2, 4, 8 edges
        ch._psc_count += 1
        if ch._psc_count < 1 << psc:
            return
        ch._psc_count = 0
        if self._sync(t):
            self._reschedule(t)
        self._capture(n, t)

    def _capture(self, n: int, t: int) -> None:
        sr = self._regs["SR"]
        if sr & cc_if(n):
            sr |= cc_of(n)  # overcapture: the previous value was never read
        self._regs["SR"] = sr | cc_if(n)
        self._regs[f"CCR{n}"] = self._ep.cnt(t)
        if self._regs["DIER"] & cc_if(n):
            self._raise_irq(t)

    # -- output waveform ----------------------------------------------------------------------

    def _out_enabled(self, n: int) -> bool:
        if self._is_input(n) or not self._ccer_bits(n) & 1:
            return False
        return not self.advanced or bool(self._regs["BDTR"] & BDTR_MOE)

    def _ref_level(self, n: int, ep: _Epoch, ccr: list[int], cnt: int) -> int:
        mode = (self._ccmr_bits(n) >> 4) & 7
        if mode == OCM_PWM1:
            return int(cnt < ccr[n - 1])
        if mode == OCM_PWM2:
            return int(cnt >= ccr[n - 1])
        return int(mode == OCM_FORCE_HIGH)

    def _wave(self, n: int) -> tuple[int, int]:
        ep, ccr = self._ep, self._ccr_active
        unit = ep.psc + 1
        period_ticks = ep.arr + 1
        period = period_ticks * unit * 1_000_000_000 // self.clock_hz
        if not self._out_enabled(n):
            return 0, period
        pol = (self._ccer_bits(n) >> 1) & 1
        mode = (self._ccmr_bits(n) >> 4) & 7
        if ep.counting and mode in (OCM_PWM1, OCM_PWM2):
            high = min(ccr[n - 1], period_ticks)
            if (mode == OCM_PWM2) ^ pol:
                high = period_ticks - high
            return high * unit * 1_000_000_000 // self.clock_hz, period
        level = self._ref_level(n, ep, ccr, ep.c0) ^ pol
        return (period if level else 0), period

    def _current_wave(self, n: int) -> tuple[int, int]:
        t = self.kernel.context_ns
        if self._sync(t):
            self._reschedule(t)
        return self._wave(n)

    def _level_at(self, n: int, t: int) -> int:
        if not self._out_enabled(n):
            return 0
        ep, ccr = self._epoch_at(t)
        pol = (self._ccer_bits(n) >> 1) & 1
        return self._ref_level(n, ep, ccr, ep.cnt(t)) ^ pol

    def _notify(self, t: int) -> None:
        for ch in self._ch:
            wave = self._wave(ch.n)
            if wave != self._waves[ch.n - 1]:
                self._waves[ch.n - 1] = wave
                for listener in tuple(ch._listeners):
                    listener(t, wave[0], wave[1])

    def _log_once(self, key: str, message: str) -> None:
        if key not in self._logged:
            self._logged.add(key)
            log.warning("timer %s: %s", self.name, message)

    def __repr__(self) -> str:
        return f"<Timer {self.name} {self.clock_hz} Hz {self.bits} bit>"
