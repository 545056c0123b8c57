"""The STM32 firmware binary in lockstep with the project's physics (sim/), and its native
reference run.

``Stm32Board`` runs the ELF on the emulated Nucleo-F446RE (emu.py, periph.py). Time follows the
host port's model (firmware/ports/host, host_advance_ns): control ticks at multiples of 1 ms, the
physics in between, I2C bus events at their instants (one byte time of 9 bits each, as
``asserv.sim.Simulator``). At a tick the physics stands still while the CPU runs the SysTick
handler: the encoder timers, GPIO and ADC inputs show the physics of that instant, and the duties
the handler leaves in TIM1 and the direction pins drive the physics from that instant. The I2C
master's bytes reach the slave model, whose interrupts run the firmware's handler at once.

``Reference`` is the same core built for the host (asserv.sim._core), stepped the same way and fed
what the port measures (its current-sense quantisation, four line inputs) and driving the
physics with the duty TIM1 produces (its 9000-count PWM period): the run the binary must match
bit for bit. Both classes are I2C devices and clocks for ``asserv.bus.VirtualBus``, so
``asserv.Board`` drives either.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from random import Random
from typing import Any

from emu import IRQ0, SRAM_BASE, SRAM_SIZE, SYSTICK, Cpu, EmuError, mmio_map, struct_padding
from periph import Adc, Flash, Gpio, I2c, Iwdg, Pwr, Rcc, Regs, Scs, Timer
from unicorn import UC_HOOK_CODE
from unicorn.arm_const import UC_ARM_REG_R1

from asserv.bus import VirtualBus
from asserv.sim._core import ffi, lib

IRQ_I2C1_EV, IRQ_I2C1_ER = 31, 32
PWM_PERIOD = 9000  # TIM1 ARR + 1 at 180 MHz, 20 kHz (stm32_clock.h)
ADC_CH_LEFT, ADC_CH_RIGHT = 4, 8
TICK_NS = 1_000_000
RESET_POWER_ON = 0  # RESET_CAUSE_POWER_ON (protocol/messages.toml)
SYSCLK_HZ = 180_000_000


def pwm_counts(duty_q15: int) -> int:
    """stm32_pwm_counts() of firmware/ports/stm32/stm32_port.h."""
    return (abs(duty_q15) * PWM_PERIOD + 16384) >> 15


def duty_of(high: int, period: int, sign: int) -> int:
    """The duty the motor sees [2^-15] for a PWM high time of ``high`` counts of ``period``."""
    return sign * min(32767, (high * 32768 + period // 2) // period)


def adc_code(current_ma: int) -> int:
    """The sense amplifier's 12-bit reading: 1.65 V at 0 A, 100 mV/A, 3.3 V reference."""
    return max(0, min(4095, 2048 + round(current_ma * 4096 / 33000)))


def current_ma(code: int) -> int:
    """stm32_current_ma() of stm32_port.h."""
    return ((code - 2048) * 33000) >> 12


class _Lockstep:
    """Time, the bus and the physics, shared by the binary's run and the reference."""

    def __init__(self, sc: Any, f: Any, byte_ns: int) -> None:
        self.sim = ffi.new("struct sim *")
        if lib.sim_init(self.sim, sc, f):
            raise ValueError("the simulator refused this configuration")
        self.byte_ns = byte_ns
        self.now_ns = 0
        self.ticks = 0
        self.bus = VirtualBus({2: self}, clock=self)
        self.sensors = ffi.new("struct sim_sensors *")
        self.trace: list[bytes] | None = None  # per tick: a digest of struct board (record())
        self.replies: list[bytes] = []  # every read transaction's bytes
        self.padding: list[int] = []  # struct board's padding bytes (Stm32Board sets them)

    def read_sensors(self) -> Any:
        lib.sim_read_sensors(self.sim, self.sensors)
        return self.sensors

    def control_tick(self) -> None:
        raise NotImplementedError

    def advance_ns(self, duration_ns: int) -> None:
        end = self.now_ns + duration_ns
        while self.now_ns < end:
            if self.now_ns == self.ticks * TICK_NS:
                self.control_tick()
                self.ticks += 1
                if self.trace is not None:
                    self.trace.append(hashlib.blake2b(self.board_state(), digest_size=16).digest())
            nxt = min(self.ticks * TICK_NS, end)
            if nxt <= self.now_ns:
                break  # a stall of the CPU on the flash moved the time past the end
            lib.sim_advance_ns(self.sim, nxt - self.now_ns)
            self.time_passes(nxt - self.now_ns)
            self.now_ns = nxt

    def time_passes(self, ns: int) -> None:
        """Between two events: what runs on its own (the watchdog)."""

    # Clock (asserv.bus.Clock).
    def monotonic(self) -> float:
        return self.now_ns * 1e-9

    def sleep(self, seconds: float) -> None:
        self.advance_ns(round(seconds * 1e9))

    # I2C device (asserv.bus.I2CDevice), timed as asserv.sim.Simulator.
    def i2c_write(self, data: bytes, stop: bool) -> None:
        self.advance_ns(self.byte_ns)
        self.ev_start(False)
        for b in data:
            self.advance_ns(self.byte_ns)
            self.ev_byte(b)
        if stop:
            self.ev_stop()

    def i2c_read(self, n: int) -> bytes:
        self.advance_ns(self.byte_ns)
        self.ev_start(True)
        out = []
        for i in range(n):
            out.append(self.ev_read())
            self.advance_ns(self.byte_ns)
            self.ev_read_end(i + 1 < n)
        self.replies.append(bytes(out))
        return bytes(out)

    def ev_start(self, read: bool) -> None:
        raise NotImplementedError

    def ev_byte(self, b: int) -> None:
        raise NotImplementedError

    def ev_stop(self) -> None:
        raise NotImplementedError

    def ev_read(self) -> int:
        raise NotImplementedError

    def ev_read_end(self, ack: bool) -> None:
        raise NotImplementedError

    def board_bytes(self) -> bytes:
        raise NotImplementedError

    def board_state(self, padding: list[int] | None = None) -> bytes:
        """struct board's bytes, its padding zeroed (see emu.struct_padding)."""
        raw = bytearray(self.board_bytes())
        for i in self.padding if padding is None else padding:
            raw[i] = 0
        return bytes(raw)


class Reference(_Lockstep):
    """The native run: asserv.sim._core's board_tick() on the port's measurements."""

    def __init__(self, bc: Any, sc: Any, f: Any, byte_ns: int = 90_000) -> None:
        super().__init__(sc, f, byte_ns)
        self.board = ffi.new("struct board *")
        self.inp = ffi.new("struct board_inputs *")
        self.out = ffi.new("struct board_outputs *")
        self._inputs()
        # As the port starts at power-on (main.c): board_restart(), which keeps its record.
        if lib.board_restart(self.board, bc, self.inp, RESET_POWER_ON, 0):
            raise ValueError("the board refused this configuration")
        self.proto = ffi.addressof(self.board, "proto")
        self.duty = (0, 0)

    def _inputs(self) -> None:
        s = self.read_sensors()
        for i in range(2):
            self.inp.free_count[i] = s.enc_count[i]
            self.inp.motor_count[i] = s.motor_count[i]
            ma = max(-32767, min(32767, s.current_mA[i]))
            self.inp.current_ma[i] = current_ma(adc_code(ma))
        self.inp.shocks = s.shock_mask
        self.inp.basket = 1 if s.basket else 0
        self.inp.lines = s.line_mask & 0x0F

    def control_tick(self) -> None:
        self._inputs()
        lib.board_tick(self.board, self.inp, self.out)
        d = [
            duty_of(pwm_counts(v), PWM_PERIOD, 1 if v > 0 else -1 if v < 0 else 0)
            for v in self.out.duty_q15
        ]
        self.duty = (d[0], d[1])
        lib.sim_set_duty(self.sim, d[0], d[1])

    def ev_start(self, read: bool) -> None:
        (lib.proto_on_read_start if read else lib.proto_on_write_start)(self.proto)

    def ev_byte(self, b: int) -> None:
        lib.proto_on_byte(self.proto, b)

    def ev_stop(self) -> None:
        lib.proto_on_stop(self.proto)

    def ev_read(self) -> int:
        return int(lib.proto_read_byte(self.proto))

    def ev_read_end(self, ack: bool) -> None:
        if not ack:
            lib.proto_on_stop(self.proto)

    def board_bytes(self) -> bytes:
        return bytes(ffi.buffer(self.board))


class Stm32Board(_Lockstep):
    """The firmware binary on the emulated chip, on the physics."""

    def __init__(
        self,
        elf: str | Path,
        sc: Any,
        f: Any,
        bc: Any = None,
        byte_ns: int = 90_000,
        nvm: bytes | None = None,
        boot_elf: str | Path | None = None,
        nvm_b: bytes | None = None,
    ) -> None:
        """``nvm``, ``nvm_b``: flash sectors 1 and 7 (the calibration's two logs) at power-on,
        16 and 128 KiB at most, the rest erased; default: all erased (a new chip).
        ``boot_elf``: the bootloader in sector 0, started at reset (boot.py); without it the
        application starts directly."""
        super().__init__(sc, f, byte_ns)
        cpu = self.cpu = Cpu(elf, boot_elf)
        self.rcc = Rcc(0x4002_3800)
        self.pwr = Pwr(0x4000_7000)
        self.flash = self._make_flash()
        self.flash.stall_on_sr = True  # the CPU fetches from this flash: see Flash
        self.flash.on_stall = self._code_stall
        for name, given, area in (
            ("nvm", nvm, self.flash.data),
            ("nvm_b", nvm_b, self.flash.data_b),
        ):
            if given is not None:
                if len(given) > len(area):
                    raise ValueError(f"{name} holds at most {len(area)} bytes")
                area[: len(given)] = given
        self.flash.attach_sector(cpu.uc)
        # Runtime stalls of the CPU on a flash operation [ns], and the control ticks they ate.
        self.stalls: list[int] = []
        self.stall_duties: list[tuple[int, int]] = []  # the duty the robot had in each
        self.lost_ticks = 0
        self.boot_stall_ns = 0
        self.power_cycles = 0
        self.resets = 0  # reset() calls
        self.gpio = {p: Gpio(0x4002_0000 + 0x400 * i) for i, p in enumerate("ABC")}
        self.tim = {
            1: Timer(0x4001_0000, advanced=True),
            2: Timer(0x4000_0000, bits=32),
            3: Timer(0x4000_0400),
            4: Timer(0x4000_0800),
            5: Timer(0x4000_0C00, bits=32),
        }
        self.adc = Adc(0x4001_2000)
        self.adc_common = Regs(0x4001_2300)  # ADC_CCR: storage only
        self.i2c = I2c(0x4000_5400)
        self.iwdg = Iwdg(0x4000_3000)
        self.scs = Scs(self._vtor)
        self.ticks_on = True  # False: SysTick raised no more, as if the firmware hung
        self.watchdog_resets = 0
        for p in (self.rcc, self.pwr, self.flash, self.i2c, self.iwdg, self.scs):
            p.attach(cpu.uc)
        for g in self.gpio.values():
            g.attach(cpu.uc)
        for t in self.tim.values():
            t.attach(cpu.uc)
        # ADC1 and the common registers share one 1 KiB block (RM0390 Table 1).
        mmio_map(cpu.uc, 0x4001_2000, 0x400, self._adc_rd, None, self._adc_wr, None)
        cpu.priority = self._priority
        cpu.enabled = lambda exc: self.scs.irq_enabled(exc - IRQ0)
        cpu.irq_lines.append(self._i2c_lines)
        self.config_override = bc
        if bc is not None:
            at = cpu.symbols["board_restart"] & ~1
            cpu.uc.hook_add(UC_HOOK_CODE, self._inject_config, begin=at, end=at)
        self.encoders = {
            # (timer, physics field, side): the free wheels on TIM3/TIM4, motors on TIM5/TIM2
            3: ("enc_total", 0),
            4: ("enc_total", 1),
            5: ("motor_total", 0),
            2: ("motor_total", 1),
        }
        s = self.read_sensors()
        self._enc_pos = {t: int(getattr(s, fld)[side]) for t, (fld, side) in self.encoders.items()}
        self.duty = (0, 0)
        self._drive_inputs(move_encoders=False)
        self._boot()
        self.proto_addr = cpu.symbols["asserv_board"] + self._layout()[2]
        self.padding = struct_padding(elf, "board")

    def _make_flash(self) -> Flash:
        return Flash(0x4002_3C00)

    def _boot(self) -> None:
        stalled = self.flash.stalled_ns
        self.cpu.reset()
        self.cpu.run_until_idle()
        self._check_flash()
        self.boot_stall_ns = self.flash.stalled_ns - stalled
        self._check_boot()

    def _code_stall(self, wait_ns: int) -> None:
        """The code waits for a flash operation (a start-up erase: the start-up runs in no
        simulated time here; an interrupt's wait has checked the watchdog first,
        _wait_for_flash): a watchdog already counting (the bootloader starts it) must outlast
        it."""
        if self.iwdg.running and wait_ns >= self.iwdg.left_ns:
            self.flash.faults.append(
                f"the watchdog ({self.iwdg.left_ns / 1e6:.0f} ms left) resets the chip in a "
                f"{wait_ns / 1e6:.0f} ms flash stall of the start-up"
            )

    def time_passes(self, ns: int) -> None:
        self.flash.advance(ns)  # the CPU sleeps: no fetch waits for the flash
        self.iwdg.advance(ns)
        if self.iwdg.expired:
            self._watchdog_reset()

    def _watchdog_reset(self) -> None:
        """The watchdog's reset: every peripheral to its reset state (the PWM stops at once:
        TIM1 off), the CPU from its reset vector, the firmware booting again on the robot as
        it is (the encoder inputs keep their phase: they are wires). A flash operation in
        progress stops part way (Flash.cut)."""
        self.watchdog_resets += 1
        self.flash.cut(Random(self.watchdog_resets))
        self._restart(Rcc.IWDGRSTF | Rcc.PINRSTF)

    def reset(
        self,
        flags: int,
        scramble: Random | None = None,
        down_ns: int = 0,
        cut: Random | None = None,
    ) -> None:
        """A reset now, between two events, that leaves RCC_CSR's reset ``flags`` (Rcc's, e.g.
        BORRSTF | PINRSTF for a brown-out): the motors off at once, the robot coasting for
        ``down_ns`` (the board down: the reset, the bootloader, the start-up up to the
        encoders counting again), then the firmware booting again. The RAM keeps its contents,
        or with ``scramble`` is filled with bytes drawn from it (the supply fell too low). A
        flash operation in progress stops part way (RM0390 3.5: its result is not
        guaranteed), what it leaves drawn from ``cut`` (default: from the count of resets)."""
        self.resets += 1
        self.flash.cut(cut if cut is not None else Random(self.resets))
        if scramble is not None:
            self.cpu.uc.mem_write(SRAM_BASE, scramble.randbytes(SRAM_SIZE))
        self.duty = (0, 0)
        lib.sim_set_duty(self.sim, 0, 0)
        self.tim[1].mem.clear()
        self.tim[1].reset_values()  # TIM1 off: no PWM while the board is down
        lib.sim_advance_ns(self.sim, down_ns)
        self.now_ns += down_ns
        # The encoder timers are held in reset: the edges of the coast are lost, the inputs'
        # phase moves with the wheels.
        s = self.read_sensors()
        for t, (fld, side) in self.encoders.items():
            pos = int(getattr(s, fld)[side])
            self.tim[t].phase = (self.tim[t].phase + pos - self._enc_pos[t]) % 4
            self._enc_pos[t] = pos
        self.ticks = max(self.ticks, -(-self.now_ns // TICK_NS))
        self._restart(flags)

    def power_cycle(self, rng: Random | None = None) -> None:
        """Power off and on now, between two events: as the watchdog's reset, and the RAM
        lost (filled with 0xA5 here); the flash keeps its contents, but for an operation in
        progress, which stops part way, drawn from ``rng``."""
        self.power_cycles += 1
        self.flash.cut(rng if rng is not None else Random(self.power_cycles))
        self.cpu.uc.mem_write(SRAM_BASE, b"\xa5" * SRAM_SIZE)
        self._restart(None)

    def _restart(self, flags: int | None) -> None:
        """flags: a system reset's RCC_CSR reset flags, added to those the CSR keeps; None: a
        power-on's."""
        kept = self.rcc.mem.get(Rcc.CSR, 0) & Rcc.RESET_FLAGS
        models = [self.rcc, self.pwr, self.flash, self.adc, self.adc_common, self.i2c, self.iwdg]
        models += [*self.gpio.values(), *self.tim.values(), self.scs]
        phases = {t: self.tim[t].phase for t in self.encoders}
        for m in models:
            m.mem.clear()
            m.reset_values()
        if flags is not None:
            self.rcc.mem[Rcc.CSR] = kept | flags
        for t, ph in phases.items():
            self.tim[t].phase = ph
        self.cpu.pending.clear()
        self.cpu.active.clear()
        self.cpu.vtor = 0x0800_0000
        self.duty = (0, 0)
        lib.sim_set_duty(self.sim, 0, 0)
        self._drive_inputs(move_encoders=False)
        self._boot()

    # ---- the CPU and the flash ---------------------------------------------------------------
    def _check_flash(self) -> None:
        if self.flash.faults:
            raise EmuError("; ".join(self.flash.faults))

    def _wait_for_flash(self, in_tick: bool) -> bool:
        """An interrupt while the flash programs or erases: the CPU fetches its handler from
        the flash, so it stalls until the operation ends (RM0390 3.5). The robot moves on
        meanwhile; the control ticks that fall in the stall are lost (on the chip, SysTick's
        pending bit keeps one of them, run at the stall's end: not modelled), and the
        watchdog counts. Returns False when the watchdog reset the chip during the stall."""
        wait = max(0, self.flash.busy_ns) if self.flash.busy() else 0
        if not wait:
            return True
        self.stalls.append(wait)
        self.stall_duties.append(self.duty)
        resets = self.watchdog_resets
        if self.iwdg.running and self.iwdg.left_ns < wait:
            wait = max(1, int(self.iwdg.left_ns) + 1)  # the watchdog resets the chip first
        else:
            self.flash.stall()
        lib.sim_advance_ns(self.sim, wait)
        self.now_ns += wait
        self.time_passes(wait)
        # The tick boundaries passed: the one running now (in_tick) is this late tick.
        ticks = self.now_ns // TICK_NS if in_tick else -(-self.now_ns // TICK_NS)
        self.lost_ticks += max(0, ticks - self.ticks)
        self.ticks = max(self.ticks, ticks)
        return self.watchdog_resets == resets

    def _run(self, in_tick: bool = False) -> bool:
        if not self._wait_for_flash(in_tick):
            return False
        self.cpu.run_until_idle()
        self._check_flash()
        self._outputs()  # the tick's duties; the main loop's, which stops the motors to erase
        return True

    # ---- wiring ---------------------------------------------------------------------------
    def _vtor(self, value: int) -> None:
        self.cpu.vtor = value

    def _priority(self, exc: int) -> int:
        if exc == SYSTICK:
            return self.scs.systick_priority()
        if exc >= IRQ0:
            return self.scs.irq_priority(exc - IRQ0)
        return -1

    def _i2c_lines(self) -> set[int]:
        ev, er = self.i2c.lines()
        lines = set()
        if ev:
            lines.add(IRQ0 + IRQ_I2C1_EV)
        if er:
            lines.add(IRQ0 + IRQ_I2C1_ER)
        return lines

    def _adc_rd(self, uc: Any, off: int, size: int, user: object) -> int:
        if off >= 0x300:
            return self.adc_common._rd(uc, off - 0x300, size, user)
        return self.adc._rd(uc, off, size, user)

    def _adc_wr(self, uc: Any, off: int, size: int, value: int, user: object) -> None:
        if off >= 0x300:
            self.adc_common._wr(uc, off - 0x300, size, value, user)
        else:
            self.adc._wr(uc, off, size, value, user)

    def _layout(self) -> tuple[int, int, int]:
        a = self.cpu.symbols["stm32_layout"]
        return self.cpu.read32(a), self.cpu.read32(a + 4), self.cpu.read32(a + 8)

    def _inject_config(self, uc: Any, address: int, size: int, user: object) -> None:
        """At board_restart()'s entry: the simulated robot's configuration in place of the one
        compiled in (r1 points to it), as a team's robot.c would give it."""

        data = bytes(ffi.buffer(self.config_override))
        uc.mem_write(uc.reg_read(UC_ARM_REG_R1), data)

    def _check_boot(self) -> None:
        board_size, config_size, _ = self._layout()
        if board_size != ffi.sizeof("struct board") or config_size != ffi.sizeof(
            "struct board_config"
        ):
            raise EmuError("struct board differs between the ARM build and the host build")
        hz = self.rcc.sysclk_hz()
        if hz != SYSCLK_HZ:
            raise EmuError(f"system clock {hz} Hz, not {SYSCLK_HZ}")
        if hz > 168_000_000 and not self.pwr.overdrive():
            raise EmuError("above 168 MHz without the over-drive (RM0390 5.1.4)")
        if self.flash.latency() < 5:
            raise EmuError(f"{self.flash.latency()} flash wait states at 180 MHz (5 needed)")
        if not self.scs.systick_on():
            raise EmuError("SysTick is not running")
        if not self.iwdg.running or abs(self.iwdg.reload_ns() - 60e6) > 1:
            raise EmuError("the watchdog is not running with its 60 ms")
        period = self.scs.systick_period_clocks(hz)
        if abs(period - TICK_NS * 1e-9) > 1e-12:
            raise EmuError(f"SysTick period {period} s, not 1 ms")

    # ---- the inputs and outputs at a tick -----------------------------------------------
    def _drive_inputs(self, move_encoders: bool = True) -> None:
        s = self.read_sensors()
        if move_encoders:
            for t, (fld, side) in self.encoders.items():
                pos = int(getattr(s, fld)[side])
                self.tim[t].quadrature_move(pos - self._enc_pos[t])
                self._enc_pos[t] = pos
        c = self.gpio["C"]
        for pin in range(8):
            c.drive(pin, 0 if s.shock_mask >> pin & 1 else None)  # switch to ground
        c.drive(8, 0 if s.basket else None)
        for i in range(4):
            c.drive(9 + i, s.line_mask >> i & 1)
        for ch, side in ((ADC_CH_LEFT, 0), (ADC_CH_RIGHT, 1)):
            self.adc.codes[ch] = adc_code(max(-32767, min(32767, s.current_mA[side])))

    def _motor_duty(self, ch: int, in1: tuple[str, int], in2: tuple[str, int]) -> int:
        high, period = self.tim[1].pwm_fraction(ch)
        a, b = self.gpio[in1[0]].out(in1[1]), self.gpio[in2[0]].out(in2[1])
        sign = 1 if (a, b) == (1, 0) else -1 if (a, b) == (0, 1) else 0
        return duty_of(high, period, sign)

    def control_tick(self) -> None:
        if self.ticks_on and not self._wait_for_flash(in_tick=True):
            return
        self._drive_inputs()
        if not self.ticks_on:
            return
        self.cpu.pending.add(SYSTICK)
        self._run(in_tick=True)

    def _outputs(self) -> None:
        """After the CPU ran: the duty TIM1 and the direction pins give drives the physics
        (the PWM period that follows takes the new compares)."""
        self.tim[1].update_event()
        left = self._motor_duty(0, ("B", 4), ("B", 5))
        right = self._motor_duty(1, ("B", 13), ("B", 14))
        if (left, right) != self.duty:
            self.duty = (left, right)
            lib.sim_set_duty(self.sim, left, right)

    # ---- the I2C master -----------------------------------------------------------------
    def ev_start(self, read: bool) -> None:
        if not self.i2c.start(2, read):
            raise OSError("the STM32 did not acknowledge its address")
        self._run()
        if self.i2c.addr_pending():
            raise EmuError("ADDR still set: the firmware holds the clock")

    def ev_byte(self, b: int) -> None:
        self.i2c.write_byte(b)
        self._run()

    def ev_stop(self) -> None:
        self.i2c.stop()
        self._run()

    def ev_read(self) -> int:
        return self.i2c.read_byte_begin()

    def ev_read_end(self, ack: bool) -> None:
        self.i2c.read_byte_end(ack)
        self._run()
        if not ack:
            self.i2c.stop()

    def board_bytes(self) -> bytes:
        a = self.cpu.symbols["asserv_board"]
        return bytes(self.cpu.uc.mem_read(a, ffi.sizeof("struct board")))


def robot(
    config: dict[str, Any] | None = None,
    seed: int = 0,
    field: Any = None,
    randomize: bool = False,
    start_uncertainty: tuple[float, float] = (0.0, 0.0),
) -> tuple[Any, Any, Any]:
    """(board config, sim config, field) of a robot as asserv.sim.Simulator makes them."""
    from asserv.sim import Simulator

    return of_simulator(
        Simulator(
            config, seed, field=field, randomize=randomize, start_uncertainty=start_uncertainty
        )
    )


def of_simulator(s: Any) -> tuple[Any, Any, Any]:
    """(board config, sim config, field) copied from an asserv.sim.Simulator (a scenario's)."""
    bc = ffi.new("struct board_config *")
    ffi.memmove(bc, ffi.addressof(s._h.board, "cfg"), ffi.sizeof("struct board_config"))
    sc = ffi.new("struct sim_config *")
    ffi.memmove(sc, s._sc, ffi.sizeof("struct sim_config"))
    f = ffi.new("struct sim_field *")
    ffi.memmove(f, s._f, ffi.sizeof("struct sim_field"))
    return bc, sc, f
