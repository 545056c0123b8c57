"""Models of the STM32F446 peripherals the port uses, register by register, after RM0390 (rev 6)
and PM0214 (the Cortex-M4 core peripherals). Each class names the sections it follows; only
the registers and bits the port touches behave, the others read back what was written."""

from __future__ import annotations

from collections.abc import Callable
from random import Random

from emu import mmio_map
from unicorn.unicorn_py3.unicorn import Uc

HSE_HZ = 8_000_000  # the ST-LINK's MCO on OSC_IN
FLASH_BASE = 0x0800_0000
# The sectors the application programs and erases, the calibration's two logs
# (firmware/ports/stm32/stm32_nvm.h): (sector, address, size), RM0390 3.3, Table 4.
NVM_SECTORS = ((1, 0x0800_4000, 0x4000), (7, 0x0806_0000, 0x2_0000))
# Typical erase times at x8, x16, x32 by sector size (STM32F446xC/E data sheet, "Flash memory
# programming": tERASE16KB, tERASE64KB, tERASE128KB) [ns].
SECTOR_ERASE_NS = {
    0x4000: (400_000_000, 300_000_000, 250_000_000),
    0x1_0000: (1_200_000_000, 700_000_000, 550_000_000),
    0x2_0000: (2_000_000_000, 1_300_000_000, 1_000_000_000),
}


class Regs:
    """A block of 32-bit registers mapped as IO (emu.mmio_map). Subclasses override
    ``read``/``write`` for the registers that behave; the others are plain storage."""

    size = 0x400

    def __init__(self, base: int) -> None:
        self.base = base
        self.mem: dict[int, int] = {}
        self.reset_values()

    def reset_values(self) -> None:
        pass

    def attach(self, uc: Uc) -> None:
        mmio_map(uc, self.base, self.size, self._rd, None, self._wr, None)

    def _rd(self, uc: object, offset: int, size: int, user: object) -> int:
        aligned = offset & ~3
        value = self.read(aligned)
        return (value >> (8 * (offset & 3))) & ((1 << (8 * size)) - 1)

    def _wr(self, uc: object, offset: int, size: int, value: int, user: object) -> None:
        aligned = offset & ~3
        if size < 4:  # byte and halfword writes: merge (the NVIC's priority bytes)
            shift = 8 * (offset & 3)
            mask = ((1 << (8 * size)) - 1) << shift
            value = (self.mem.get(aligned, 0) & ~mask) | ((value << shift) & mask)
        self.write(aligned, value & 0xFFFFFFFF)

    def read(self, off: int) -> int:
        return self.mem.get(off, 0)

    def write(self, off: int, value: int) -> None:
        self.mem[off] = value


# ---- RCC, PWR, flash interface ---------------------------------------------------------------
class Rcc(Regs):
    """RM0390 6.3: the HSE ready flag follows HSEON (bypass: at once), the PLL's follows PLLON
    once its source is ready, SWS follows SW only to a ready source (6.3.1, 6.3.3). PLLCFGR is
    taken only while the PLL is off (6.3.2). CSR's reset flags (6.3.21) read as a power-on
    left them (PORRSTF, BORRSTF, PINRSTF) until RMVF clears them; a system reset keeps them
    and adds its own (``Stm32Board.reset``)."""

    CR, PLLCFGR, CFGR, CSR = 0x00, 0x04, 0x08, 0x74
    HSEON, HSERDY, HSEBYP, PLLON, PLLRDY = 1 << 16, 1 << 17, 1 << 18, 1 << 24, 1 << 25
    HSION, HSIRDY = 1 << 0, 1 << 1
    RMVF, BORRSTF, PINRSTF, PORRSTF = 1 << 24, 1 << 25, 1 << 26, 1 << 27
    SFTRSTF, IWDGRSTF, WWDGRSTF, LPWRRSTF = 1 << 28, 1 << 29, 1 << 30, 1 << 31
    RESET_FLAGS = 0xFE00_0000

    def reset_values(self) -> None:
        self.mem[self.CR] = 0x0000_0083  # HSION, HSIRDY, trim
        self.mem[self.PLLCFGR] = 0x2400_3010
        self.mem[self.CFGR] = 0
        self.mem[self.CSR] = self.PORRSTF | self.BORRSTF | self.PINRSTF

    def write(self, off: int, value: int) -> None:
        if off == self.CR:
            ready = 0
            if value & self.HSION:
                ready |= self.HSIRDY
            if value & self.HSEON:
                ready |= self.HSERDY
            pll_src_ready = ready & (self.HSERDY if self._pllsrc_hse() else self.HSIRDY)
            if value & self.PLLON and pll_src_ready:
                ready |= self.PLLRDY
            rw = ~(self.HSIRDY | self.HSERDY | self.PLLRDY) & 0xFFFFFFFF
            self.mem[off] = (value & rw) | ready
        elif off == self.PLLCFGR:
            if not self.mem[self.CR] & self.PLLON:
                self.mem[off] = value
        elif off == self.CFGR:
            sw = value & 3
            sws = (self.mem[self.CFGR] >> 2) & 3
            if self._source_ready(sw):
                sws = sw
            self.mem[off] = (value & ~0xC) | sws << 2
        elif off == self.CSR:
            flags = 0 if value & self.RMVF else self.mem[self.CSR] & self.RESET_FLAGS
            lsi = (value & 1) << 1  # LSIRDY follows LSION at once
            self.mem[off] = flags | (value & 1) | lsi
        else:
            self.mem[off] = value

    def _pllsrc_hse(self) -> bool:
        return bool(self.mem[self.PLLCFGR] & (1 << 22))

    def _source_ready(self, sw: int) -> bool:
        cr = self.mem[self.CR]
        return bool(cr & [self.HSIRDY, self.HSERDY, self.PLLRDY, 0][sw])

    def pll_hz(self) -> int:
        c = self.mem[self.PLLCFGR]
        m, n, p = c & 0x3F, (c >> 6) & 0x1FF, 2 * (((c >> 16) & 3) + 1)
        src = HSE_HZ if self._pllsrc_hse() else 16_000_000
        return src * n // m // p

    def sysclk_hz(self) -> int:
        sws = (self.mem[self.CFGR] >> 2) & 3
        return [16_000_000, HSE_HZ, self.pll_hz(), 0][sws]

    def apb_div(self, bus: int) -> int:
        bits = (self.mem[self.CFGR] >> (10 if bus == 1 else 13)) & 7
        return 1 if bits < 4 else 2 << (bits - 4)


class Pwr(Regs):
    """RM0390 5.4: ODRDY follows ODEN, ODSWRDY follows ODSWEN once ODRDY is set (5.1.4)."""

    CR, CSR = 0x00, 0x04
    ODEN, ODSWEN = 1 << 16, 1 << 17
    ODRDY, ODSWRDY = 1 << 16, 1 << 17

    def reset_values(self) -> None:
        self.mem[self.CR] = 0x0000_C000
        self.mem[self.CSR] = 0

    def write(self, off: int, value: int) -> None:
        self.mem[off] = value
        if off == self.CR:
            csr = 0
            if value & self.ODEN:
                csr |= self.ODRDY
                if value & self.ODSWEN:
                    csr |= self.ODSWRDY
            self.mem[self.CSR] = csr

    def overdrive(self) -> bool:
        return bool(self.mem[self.CSR] & self.ODSWRDY)


class Flash(Regs):
    """The embedded flash interface, RM0390 3 (registers 3.8), and the sectors it programs
    (``NVM_SECTORS``: 1 and 7, the calibration's logs; ``data`` is sector 1, ``data_b`` sector
    7). Operations name their place by its offset from the flash's base.

    - FLASH_ACR (3.8.1): LATENCY reads back what was written (3.4.1).
    - Unlock (3.5.1): FLASH_CR is locked at reset (LOCK); KEY1 then KEY2 written to FLASH_KEYR
      clears LOCK. Any other value, or a key while unlocked, is a bus error (``faults``) and
      locks FLASH_CR until the next reset. Writing LOCK locks it again. A locked CR ignores
      writes.
    - Program (3.5.4): with PG set, a store into the sector of the size PSIZE says (x8, x16,
      x32) programs it, 1 bits to 0 only (the result is old AND new: 0 to 1 needs an erase);
      a store of another size sets PGPERR, one not aligned to its size PGAERR, one without PG
      PGSERR, and nothing is written. BSY for ``PROGRAM_NS``.
    - Erase (3.5.3): SER, SNB and STRT erase a sector to 0xFF; BSY for ``SECTOR_ERASE_NS`` of
      its size and the PSIZE (the data sheet's typical figures); STRT reads 1 until BSY clears.
      Erasing another sector than the modelled ones, or a mass erase, would erase the
      firmware's code: a fault. The operation's result appears when it ends (``advance``,
      ``finish``).
    - FLASH_SR (3.8.4): BSY; EOP (with EOPIE) and the error flags OPERR, WRPERR, PGAERR,
      PGPERR, PGSERR, cleared by writing 1 (rc_w1).
    - While BSY, a write to FLASH_CR and any access to the sector stall the bus until the
      operation ends (3.5, 3.6): the model ends it first and adds the wait to ``stalled_ns``.
      With ``stall_on_sr`` (the board), a read of FLASH_SR while BSY does too: the CPU fetches
      its code from this flash, so a load from FLASH_SR could only run once the flash was
      free again.
    - ``cut`` is a power-off or a reset in the middle of an operation: a word being programmed
      keeps a random part of its 1-to-0 changes, a sector being erased a random part of its
      0-to-1 changes, word by word.
    The sector's contents (``data``) survive ``reset_values``: they are the flash."""

    ACR, KEYR, SR, CR = 0x00, 0x04, 0x0C, 0x10
    KEY1, KEY2 = 0x4567_0123, 0xCDEF_89AB
    EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR, BSY = (
        1 << 0,
        1 << 1,
        1 << 4,
        1 << 5,
        1 << 6,
        1 << 7,
        1 << 16,
    )
    ERRORS = OPERR | WRPERR | PGAERR | PGPERR | PGSERR
    PG, SER, MER, STRT, EOPIE, ERRIE, LOCK = 1, 2, 4, 1 << 16, 1 << 24, 1 << 25, 1 << 31
    SNB_POS, PSIZE_POS = 3, 8
    CR_RW = PG | SER | MER | 0xF << 3 | 3 << 8 | EOPIE | ERRIE
    PROGRAM_NS = 16_000  # the data sheet's typical word (byte, half-word) programming time
    ERASE_NS = SECTOR_ERASE_NS[0x4000]  # sector 1's, at x8, x16, x32
    ERASE_B_NS = SECTOR_ERASE_NS[0x2_0000]  # sector 7's

    def __init__(self, base: int) -> None:
        self.sectors = {n: bytearray(b"\xff" * size) for n, _, size in NVM_SECTORS}
        self.data = self.sectors[1]
        self.data_b = self.sectors[7]
        self.stall_on_sr = False
        self.stalled_ns = 0  # total time the bus waited for an operation
        self.faults: list[str] = []
        self.programs = 0
        self.erases = 0
        self.erased: list[int] = []  # the sector of each erase started
        # Called with each wait of the bus (stall) before the operation ends: the board checks
        # the watchdog against a stall of the start-up, which runs in no simulated time.
        self.on_stall: Callable[[int], None] | None = None
        # When set, says whether the CPU fetches from the flash now (stall_on_sr's value).
        self.code_in_flash: Callable[[], bool] | None = None
        super().__init__(base)

    def reset_values(self) -> None:
        self.mem[self.ACR] = 0
        self.mem[self.CR] = self.LOCK
        self.sr = 0
        self.key_stage = 0
        self.locked_out = False  # a wrong key: FLASH_CR locked until the next reset
        self.op: tuple[str, int, int, int] | None = None  # (kind, offset, size, value)
        self.busy_ns = 0

    def latency(self) -> int:
        return self.mem[self.ACR] & 0xF

    def psize(self) -> int:
        return (self.mem[self.CR] >> self.PSIZE_POS) & 3

    def busy(self) -> bool:
        return self.op is not None

    # ---- time -------------------------------------------------------------------------------
    def advance(self, ns: int) -> None:
        if self.op is not None:
            self.busy_ns -= ns
            if self.busy_ns <= 0:
                self.finish()

    def stall(self) -> int:
        """The bus waits for the operation in progress: it ends now. Returns the wait [ns]."""
        if self.op is None:
            return 0
        wait = max(0, self.busy_ns)
        if self.on_stall is not None:
            self.on_stall(wait)
        self.stalled_ns += wait
        self.finish()
        return wait

    def finish(self) -> None:
        if self.op is None:
            return
        kind, off, size, value = self.op
        buf, at = self._locate(off)
        if kind == "program":
            for i in range(size):
                buf[at + i] &= (value >> (8 * i)) & 0xFF
        else:
            buf[:] = b"\xff" * len(buf)
        self.op = None
        self.busy_ns = 0
        self.mem[self.CR] &= ~self.STRT
        if self.mem[self.CR] & self.EOPIE:
            self.sr |= self.EOP

    def cut(self, rng: Random) -> None:
        """A power-off or a reset now: the operation in progress stops part way."""
        if self.op is None:
            return
        kind, off, size, value = self.op
        buf, at = self._locate(off)
        if kind == "program":
            for i in range(size):
                done = rng.getrandbits(8)  # the 1-to-0 changes that happened
                buf[at + i] &= ((value >> (8 * i)) & 0xFF) | ~done & 0xFF
        else:
            for i in range(0, len(buf), 4):
                done = rng.getrandbits(32)  # the 0-to-1 changes that happened
                word = int.from_bytes(buf[i : i + 4], "little") | done
                buf[i : i + 4] = word.to_bytes(4, "little")
        self.op = None
        self.busy_ns = 0

    # ---- registers ----------------------------------------------------------------------------
    def read(self, off: int) -> int:
        if off == self.SR:
            fetching = self.code_in_flash() if self.code_in_flash else self.stall_on_sr
            if self.op is not None and fetching:
                self.stall()
            return self.sr | (self.BSY if self.op is not None else 0)
        if off == self.KEYR:
            return 0
        return self.mem.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == self.KEYR:
            self._key(value)
        elif off == self.SR:
            self.sr &= ~(value & (self.ERRORS | self.EOP))
        elif off == self.CR:
            self.stall()
            self._cr(value)
        else:
            self.mem[off] = value

    def _key(self, value: int) -> None:
        cr = self.mem[self.CR]
        if self.locked_out or not cr & self.LOCK:
            self._bus_error("a key written to FLASH_KEYR while FLASH_CR is unlocked or locked out")
            return
        if self.key_stage == 0 and value == self.KEY1:
            self.key_stage = 1
        elif self.key_stage == 1 and value == self.KEY2:
            self.key_stage = 0
            self.mem[self.CR] = cr & ~self.LOCK
        else:
            self._bus_error(f"wrong flash key 0x{value:08x}")

    def _bus_error(self, why: str) -> None:
        self.locked_out = True
        self.key_stage = 0
        self.faults.append(f"bus error: {why}; FLASH_CR locked until reset (RM0390 3.5.1)")

    def _cr(self, value: int) -> None:
        cr = self.mem[self.CR]
        if cr & self.LOCK:
            return
        self.mem[self.CR] = (value & self.CR_RW) | (self.LOCK if value & self.LOCK else 0)
        if value & self.STRT and not value & self.LOCK:
            if value & self.MER:
                self.faults.append("a mass erase: it would erase the firmware")
            elif value & self.SER:
                snb = (value >> self.SNB_POS) & 0xF
                if snb not in self.sectors:
                    self.faults.append(f"an erase of sector {snb}: it holds the firmware")
                    return
                if self.psize() == 3:
                    self.faults.append("an erase at x64: it needs an external VPP (3.6.2)")
                    return
                _, addr, size = next(x for x in NVM_SECTORS if x[0] == snb)
                self.mem[self.CR] |= self.STRT
                self.op = ("erase", addr - FLASH_BASE, size, 0)
                self.busy_ns = SECTOR_ERASE_NS[size][self.psize()]
                self.erases += 1
                self.erased.append(snb)

    # ---- the sectors (mapped at their addresses) ----------------------------------------------
    def _locate(self, off: int) -> tuple[bytearray, int]:
        """The sector's bytes that hold flash offset ``off``, and its index in them."""
        for n, addr, size in NVM_SECTORS:
            if 0 <= off - (addr - FLASH_BASE) < size:
                return self.sectors[n], off - (addr - FLASH_BASE)
        raise ValueError(f"flash offset 0x{off:x} is outside the modelled sectors")

    def attach_sector(self, uc: Uc) -> None:
        for _, addr, size in NVM_SECTORS:
            base = addr - FLASH_BASE  # each access's offset is the sector's: user adds this
            mmio_map(uc, addr, size, self._array_rd, base, self._array_wr, base)

    def _array_rd(self, uc: object, offset: int, size: int, user: int) -> int:
        self.stall()
        buf, at = self._locate(user + offset)
        return int.from_bytes(buf[at : at + size], "little")

    def _array_wr(self, uc: object, offset: int, size: int, value: int, user: int) -> None:
        self.program(user + offset, size, value)

    def program(self, offset: int, size: int, value: int) -> None:
        """A store of ``size`` bytes at flash offset ``offset``."""
        self.stall()
        cr = self.mem[self.CR]
        if not cr & self.PG:
            self.sr |= self.PGSERR
        elif size != 1 << self.psize():
            self.sr |= self.PGPERR
        elif offset % size:
            self.sr |= self.PGAERR
        else:
            self.op = ("program", offset, size, value & ((1 << (8 * size)) - 1))
            self.busy_ns = self.PROGRAM_NS
            self.programs += 1


class Iwdg(Regs):
    """The independent watchdog, RM0390 19.3-19.4: the key 0xCCCC starts it, 0xAAAA reloads its
    down-counter from RLR, 0x5555 opens PR and RLR to writes until the next key; the counter
    runs at LSI / (4 << PR) (the nominal 32 kHz here) and resets the chip when it reaches 0.
    SR's update flags are never seen set (the update takes no simulated time here)."""

    KR, PR, RLR, SR = 0x00, 0x04, 0x08, 0x0C
    LSI_HZ = 32_000

    def reset_values(self) -> None:
        self.mem[self.PR] = 0
        self.mem[self.RLR] = 0xFFF
        self.access = False
        self.running = False
        self.left_ns = 0.0
        self.expired = False

    def reload_ns(self) -> float:
        return (self.mem[self.RLR] + 1) * (4 << self.mem[self.PR]) * 1e9 / self.LSI_HZ

    def write(self, off: int, value: int) -> None:
        if off == self.KR:
            key = value & 0xFFFF
            self.access = key == 0x5555
            if key == 0xCCCC:
                self.running = True
                self.left_ns = self.reload_ns()
            elif key == 0xAAAA:
                self.left_ns = self.reload_ns()
        elif off == self.PR and self.access:
            self.mem[off] = value & 7
        elif off == self.RLR and self.access:
            self.mem[off] = value & 0xFFF

    def read(self, off: int) -> int:
        return 0 if off in (self.KR, self.SR) else self.mem.get(off, 0)

    def advance(self, ns: int) -> None:
        """Time passes; ``expired`` when the counter reaches 0."""
        if self.running:
            self.left_ns -= ns
            if self.left_ns <= 0:
                self.expired = True


# ---- GPIO -----------------------------------------------------------------------------------
class Gpio(Regs):
    """RM0390 7.4: IDR shows the pins: the level driven from outside on an input (``drive``),
    the pull-up's high on an undriven input with PUPDR 01, ODR on an output. BSRR sets the
    bits of its low half and resets those of its high half, the set winning (7.4.7)."""

    MODER, OTYPER, PUPDR, IDR, ODR, BSRR = 0x00, 0x04, 0x0C, 0x10, 0x14, 0x18

    def reset_values(self) -> None:
        self.external: dict[int, int] = {}  # pin -> level driven from outside

    def drive(self, pin: int, level: int | None) -> None:
        if level is None:
            self.external.pop(pin, None)
        else:
            self.external[pin] = 1 if level else 0

    def mode(self, pin: int) -> int:
        return (self.mem.get(self.MODER, 0) >> (2 * pin)) & 3

    def read(self, off: int) -> int:
        if off == self.IDR:
            v = 0
            odr = self.mem.get(self.ODR, 0)
            pupd = self.mem.get(self.PUPDR, 0)
            for pin in range(16):
                if self.mode(pin) == 1:
                    level = (odr >> pin) & 1
                elif pin in self.external:
                    level = self.external[pin]
                else:
                    level = 1 if (pupd >> (2 * pin)) & 3 == 1 else 0
                v |= level << pin
            return v
        if off == self.BSRR:
            return 0
        return self.mem.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == self.BSRR:
            odr = self.mem.get(self.ODR, 0)
            odr &= ~(value >> 16) & 0xFFFF
            odr |= value & 0xFFFF
            self.mem[self.ODR] = odr
        elif off != self.IDR:
            self.mem[off] = value

    def out(self, pin: int) -> int:
        return (self.mem.get(self.ODR, 0) >> pin) & 1


# ---- Timers ---------------------------------------------------------------------------------
# Encoder-mode counting direction, RM0390 17.3.16 Table 79: (edge on TI1?, rising?, other
# input's level) -> +1 (up) or -1 (down).
_ENCODER_TABLE = {
    (True, True, 0): +1,
    (True, True, 1): -1,
    (True, False, 0): -1,
    (True, False, 1): +1,
    (False, True, 1): +1,
    (False, True, 0): -1,
    (False, False, 1): -1,
    (False, False, 0): +1,
}
# The quadrature phases of a position: A leads B when the position rises.
_PHASES = ((0, 0), (1, 0), (1, 1), (0, 1))


class Timer(Regs):
    """TIM1 (RM0390 16.4) and TIM2..TIM5 (17.4). Encoder mode (SMCR.SMS 1, 2, 3: 17.3.16) counts
    the edges of TI1/TI2 (after the CC1P/CC2P polarity) up or down by Table 79, wrapping at ARR,
    DIR showing the last direction. The compare registers are preloaded when OCxPE is set:
    written values take effect at the next update event (UG, or the counter's overflow, which
    the lockstep calls ``update_event``) (16.3.10 PWM mode). The PWM output of channel n in mode
    1 is high while CNT < CCRn: its duty is min(CCRn, ARR + 1) / (ARR + 1), when CEN, CCnE and
    (TIM1) BDTR.MOE are set."""

    CR1, SMCR, SR, EGR, CCMR1, CCER, CNT, PSC, ARR = 0, 8, 0x10, 0x14, 0x18, 0x20, 0x24, 0x28, 0x2C
    CCR = (0x34, 0x38, 0x3C, 0x40)
    BDTR = 0x44

    def __init__(self, base: int, bits: int = 16, advanced: bool = False) -> None:
        self.bits = bits
        self.advanced = advanced
        super().__init__(base)

    def reset_values(self) -> None:
        self.mem[self.ARR] = (1 << self.bits) - 1
        self.arr_active = self.mem[self.ARR]
        self.ccr_active = [0, 0, 0, 0]
        self.cnt = 0
        self.phase = 0  # the quadrature inputs' position modulo 4
        self.mem[self.CR1] = 0

    def read(self, off: int) -> int:
        if off == self.CNT:
            return self.cnt
        return self.mem.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == self.CNT:
            self.cnt = value & ((1 << self.bits) - 1)
        elif off == self.EGR:
            if value & 1:
                self.update_event()
        elif off == self.CR1:
            keep_dir = self.mem[self.CR1] & 0x10 if self.encoder_mode() else value & 0x10
            self.mem[off] = (value & ~0x10) | keep_dir
        elif off == self.ARR:
            self.mem[off] = value & ((1 << self.bits) - 1)
            if not self.mem[self.CR1] & 0x80:  # ARPE
                self.arr_active = self.mem[off]
        elif off in self.CCR:
            ch = self.CCR.index(off)
            self.mem[off] = value & ((1 << self.bits) - 1)
            if not self._preload(ch):
                self.ccr_active[ch] = self.mem[off]
        else:
            self.mem[off] = value

    def _preload(self, ch: int) -> bool:
        ccmr = self.mem.get(self.CCMR1 + 4 * (ch // 2), 0)
        return bool(ccmr >> (3 + 8 * (ch % 2)) & 1)

    def update_event(self) -> None:
        """An update event: the preloaded ARR and compare values become active."""
        self.arr_active = self.mem[self.ARR]
        for ch in range(4):
            self.ccr_active[ch] = self.mem.get(self.CCR[ch], 0)
        if not self.encoder_mode():
            self.cnt = 0

    def encoder_mode(self) -> int:
        sms = self.mem.get(self.SMCR, 0) & 7
        return sms if sms in (1, 2, 3) else 0

    # Inputs: the quadrature position the harness drives on TI1 (A) and TI2 (B).
    def _edge(self, on_ti1: bool, rising: bool, other: int) -> int:
        """One input edge; returns the count step it made (+1, -1 or 0)."""
        sms = self.encoder_mode()
        if not sms or not self.mem[self.CR1] & 1:
            return 0
        if (sms == 1 and on_ti1) or (sms == 2 and not on_ti1):
            return 0  # SMS 1 counts TI2 edges only, SMS 2 TI1 edges only
        ccer = self.mem.get(self.CCER, 0)
        p1, p2 = (ccer >> 1) & 1, (ccer >> 5) & 1
        # TI1FP1 = TI1 xor CC1P, TI2FP2 = TI2 xor CC2P.
        if on_ti1:
            rising ^= bool(p1)
            other ^= p2
        else:
            rising ^= bool(p2)
            other ^= p1
        step = _ENCODER_TABLE[(on_ti1, rising, other)]
        top = self.arr_active
        if step > 0:
            self.cnt = 0 if self.cnt >= top else self.cnt + 1
            self.mem[self.CR1] &= ~0x10
        else:
            self.cnt = top if self.cnt == 0 else self.cnt - 1
            self.mem[self.CR1] |= 0x10
        return step

    def quadrature_step(self, direction: int) -> int:
        """One edge: the inputs move one quadrature phase up (+1) or down (-1). Returns the
        count step."""
        a0, _ = _PHASES[self.phase]
        self.phase = (self.phase + direction) % 4
        a1, b1 = _PHASES[self.phase]
        if a0 != a1:
            return self._edge(True, a1 == 1, b1)
        return self._edge(False, b1 == 1, a1)

    def quadrature_move(self, n: int) -> None:
        """|n| edges in one direction, as ``quadrature_step`` would count them one by one: the
        remainder modulo 4 edge by edge, then one whole cycle of 4 edges (which brings the
        inputs back to their phase), whose count change every further cycle repeats."""
        direction = 1 if n > 0 else -1
        cycles, rest = divmod(abs(n), 4)
        for _ in range(rest):
            self.quadrature_step(direction)
        if cycles:
            per_cycle = sum(self.quadrature_step(direction) for _ in range(4))
            if per_cycle and cycles > 1:
                self.cnt = (self.cnt + per_cycle * (cycles - 1)) % (self.arr_active + 1)
                self.mem[self.CR1] = (self.mem[self.CR1] & ~0x10) | (0x10 if per_cycle < 0 else 0)

    def pwm_fraction(self, ch: int) -> tuple[int, int]:
        """(high counts, period counts) of channel ch's PWM output (mode 1, upcounting)."""
        period = self.arr_active + 1
        ccer = self.mem.get(self.CCER, 0)
        on = self.mem[self.CR1] & 1 and ccer >> (4 * ch) & 1
        if self.advanced:
            on = on and self.mem.get(self.BDTR, 0) & (1 << 15)
        ccmr = self.mem.get(self.CCMR1 + 4 * (ch // 2), 0)
        mode = (ccmr >> (4 + 8 * (ch % 2))) & 7
        if not on or mode != 6:
            return 0, period
        return min(self.ccr_active[ch], period), period


# ---- ADC ------------------------------------------------------------------------------------
class Adc(Regs):
    """ADC1, RM0390 13: an injected sequence of JL + 1 conversions started by JSWSTART (13.3.8)
    converts JSQ(4 - JL) .. JSQ4 into JDR1 .. JDR(JL + 1) (13.13.12), then sets JEOC and JSTRT;
    JSWSTART clears itself. SR's flags are cleared by writing 0 (rc_w0). The inputs are 12-bit
    codes the harness sets per channel (``codes``); conversions take no simulated time."""

    SR, CR1, CR2, JSQR, JDR1 = 0x00, 0x04, 0x08, 0x38, 0x3C
    JEOC, JSTRT = 1 << 2, 1 << 3
    ADON, JSWSTART = 1 << 0, 1 << 22

    def reset_values(self) -> None:
        self.codes: dict[int, int] = {}
        self.conversions = 0

    def write(self, off: int, value: int) -> None:
        if off == self.SR:
            self.mem[off] = self.mem.get(off, 0) & value & 0x3F
        elif off == self.CR2:
            self.mem[off] = value & ~self.JSWSTART
            if value & self.JSWSTART and value & self.ADON:
                self._convert_injected()
        else:
            self.mem[off] = value

    def _convert_injected(self) -> None:
        jsqr = self.mem.get(self.JSQR, 0)
        jl = (jsqr >> 20) & 3
        for i, k in enumerate(range(3 - jl, 4)):  # JSQ(k+1), k = 3 - JL .. 3
            ch = (jsqr >> (5 * k)) & 0x1F
            self.mem[self.JDR1 + 4 * i] = self.codes.get(ch, 0) & 0xFFF
            self.conversions += 1
        self.mem[self.SR] = self.mem.get(self.SR, 0) | self.JEOC | self.JSTRT


# ---- I2C ------------------------------------------------------------------------------------
def crc8(crc: int, byte: int) -> int:
    """The SMBus PEC: CRC-8, polynomial x^8 + x^2 + x + 1 (RM0390 24.3.8)."""
    crc ^= byte
    for _ in range(8):
        crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


class I2c(Regs):
    """I2C1 in slave mode, RM0390 24.3.3 (and 24.6 registers), driven from the master's side by
    the harness (``start``, ``write_byte``, ``read_byte``, ``stop``):
    - own address + R/W acknowledged when PE and ACK are set: ADDR, and SR2.TRA for a read;
      ADDR is cleared by reading SR1 then SR2;
    - each byte received: RXNE (cleared by reading DR); one not read before the next arrives
      sets BTF and the clock is held (the harness reports it as a stall);
    - sending: TXE while DR is empty; the byte moves from DR to the shift register as it goes
      out; acknowledged with DR still empty: BTF (cleared by reading SR1 then writing DR), the
      clock held until DR is written; not acknowledged: AF (rc_w0), the slave leaves the
      transfer and no STOPF follows (Figure 245);
    - a STOP after a write: STOPF, cleared by reading SR1 then writing CR1;
    - ENPEC: SR2.PEC is the CRC-8 of every byte since the START, address included (24.3.8).
    Event interrupt: ITEVTEN and (ADDR, STOPF, BTF), or ITEVTEN, ITBUFEN and (RXNE, TXE);
    error interrupt: ITERREN and (BERR, ARLO, AF, OVR) (24.4, Table 148)."""

    CR1, CR2, OAR1, DR, SR1, SR2 = 0x00, 0x04, 0x08, 0x10, 0x14, 0x18
    PE, ENPEC, ACK, SWRST = 1 << 0, 1 << 3, 1 << 10, 1 << 15
    ITERREN, ITEVTEN, ITBUFEN = 1 << 8, 1 << 9, 1 << 10
    ADDR, BTF, STOPF, RXNE, TXE = 1 << 1, 1 << 2, 1 << 4, 1 << 6, 1 << 7
    BERR, ARLO, AF, OVR = 1 << 8, 1 << 9, 1 << 10, 1 << 11
    TRA, BUSY = 1 << 2, 1 << 1

    def reset_values(self) -> None:
        self.sr1 = 0
        self.sr2 = 0
        self.dr_rx: int | None = None  # received, not yet read
        self.dr_tx: int | None = None  # written, not yet sent
        self.sr1_read = False
        self.state = "idle"  # "rx", "tx", "idle"
        self.pec = 0
        self.mem[self.CR1] = 0
        self.mem[self.CR2] = 0

    # Register side (the firmware).
    def read(self, off: int) -> int:
        if off == self.SR1:
            self.sr1_read = True
            return self.sr1
        if off == self.SR2:
            if self.sr1_read and self.sr1 & self.ADDR:
                self.sr1 &= ~self.ADDR
                if self.state == "tx" and self.dr_tx is None:
                    self.sr1 |= self.TXE
            self.sr1_read = False
            pec = self.pec if self.mem[self.CR1] & self.ENPEC else 0
            return self.sr2 | pec << 8
        if off == self.DR:
            value = self.dr_rx if self.dr_rx is not None else 0
            self.dr_rx = None
            self.sr1 &= ~self.RXNE
            if self.sr1_read:
                self.sr1 &= ~self.BTF
            self.sr1_read = False
            return value
        return self.mem.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == self.CR1:
            if value & self.SWRST:
                self.reset_values()
                self.mem[self.CR1] = value
                return
            if not value & self.PE:
                value &= ~self.ACK  # ACK cleared while PE is 0 (24.6.1)
            if self.sr1_read and self.sr1 & self.STOPF:
                self.sr1 &= ~self.STOPF
            self.sr1_read = False
            self.mem[self.CR1] = value
        elif off == self.DR:
            if self.state == "tx":
                self.dr_tx = value & 0xFF
                self.sr1 &= ~self.TXE
                if self.sr1_read:
                    self.sr1 &= ~self.BTF
            self.sr1_read = False
        elif off == self.SR1:
            errors = 0xFF00
            self.sr1 &= (value | ~errors) & 0xFFFF
        elif off == self.SR2:
            pass
        else:
            self.mem[off] = value

    def lines(self) -> tuple[bool, bool]:
        """(event, error) interrupt lines."""
        cr2 = self.mem.get(self.CR2, 0)
        ev = bool(cr2 & self.ITEVTEN) and bool(
            self.sr1 & (self.ADDR | self.STOPF | self.BTF)
            or (cr2 & self.ITBUFEN and self.sr1 & (self.RXNE | self.TXE))
        )
        er = bool(cr2 & self.ITERREN) and bool(
            self.sr1 & (self.BERR | self.ARLO | self.AF | self.OVR)
        )
        return ev, er

    # Bus side (the master). Each returns whether the slave acknowledged.
    def _own(self, address: int) -> bool:
        cr1 = self.mem.get(self.CR1, 0)
        return (
            bool(cr1 & self.PE and cr1 & self.ACK)
            and ((self.mem.get(self.OAR1, 0) >> 1) & 0x7F) == address
        )

    def _pec_byte(self, byte: int) -> None:
        self.pec = crc8(self.pec, byte)

    def start(self, address: int, read: bool) -> bool:
        """A START (or repeated START) and the address byte."""
        if not self._own(address):
            self.state = "idle"
            return False
        self.pec = 0
        self._pec_byte(address << 1 | int(read))
        self.state = "tx" if read else "rx"
        self.dr_tx = None
        self.sr1 &= ~(self.TXE | self.BTF | self.RXNE)
        self.sr1 |= self.ADDR
        self.sr2 = self.BUSY | (self.TRA if read else 0)
        return True

    def addr_pending(self) -> bool:
        return bool(self.sr1 & self.ADDR)

    def write_byte(self, byte: int) -> bool:
        if self.state != "rx" or self.sr1 & self.ADDR:
            raise RuntimeError("I2C: a data byte while the slave holds the clock after ADDR")
        if self.dr_rx is not None:
            self.sr1 |= self.BTF
            raise RuntimeError("I2C: the last byte was not read before this one (BTF)")
        self.dr_rx = byte & 0xFF
        self.sr1 |= self.RXNE
        self._pec_byte(byte)
        return bool(self.mem.get(self.CR1, 0) & self.ACK)

    def tx_ready(self) -> bool:
        return self.state == "tx" and not self.sr1 & self.ADDR and self.dr_tx is not None

    def read_byte_begin(self) -> int:
        """The byte in DR goes to the shift register and out: TXE (DR empty)."""
        if not self.tx_ready():
            raise RuntimeError("I2C: the slave holds the clock: no byte in DR to send")
        assert self.dr_tx is not None
        byte = self.dr_tx
        self.dr_tx = None
        self.sr1 |= self.TXE
        self._pec_byte(byte)
        return byte

    def read_byte_end(self, ack: bool) -> None:
        """The master's acknowledge: BTF if DR is still empty, AF on a NACK."""
        if ack:
            if self.dr_tx is None:
                self.sr1 |= self.BTF
        else:
            self.sr1 |= self.AF
            self.sr1 &= ~(self.TXE | self.BTF)
            self.state = "idle"
            self.sr2 &= ~(self.TRA | self.BUSY)

    def stop(self) -> None:
        if self.state == "rx":
            self.sr1 |= self.STOPF
        self.state = "idle"
        self.sr2 &= ~(self.TRA | self.BUSY)


# ---- Core peripherals (PM0214) ------------------------------------------------------------
class Scs(Regs):
    """The system control space at 0xE000E000: SysTick (PM0214 4.5), the NVIC's ISER/ICER and
    priority bytes (4.2), SCB VTOR and SHPR3 (4.4). SysTick's period is RVR + 1 clocks of the
    processor clock (CLKSOURCE 1) or of HCLK / 8; the harness raises its exception at each
    period of the lockstep."""

    size = 0x1000
    SYST_CSR, SYST_RVR, SYST_CVR = 0x010, 0x014, 0x018
    ISER, ICER, IPR = 0x100, 0x180, 0x400
    VTOR, SHPR3 = 0xD08, 0xD20

    AIRCR = 0xD0C
    SYSRESETREQ = 0x05FA_0004  # PM0214 4.4.5: VECTKEY and SYSRESETREQ

    def __init__(self, on_vtor: Callable[[int], None]) -> None:
        self.on_vtor = on_vtor
        self.on_reset: Callable[[], None] | None = None  # a system reset requested (AIRCR)
        super().__init__(0xE000_E000)

    def write(self, off: int, value: int) -> None:
        if self.ICER <= off < self.ICER + 0x20:
            iser = self.ISER + (off - self.ICER)
            self.mem[iser] = self.mem.get(iser, 0) & ~value
        elif self.ISER <= off < self.ISER + 0x20:
            self.mem[off] = self.mem.get(off, 0) | value
        else:
            self.mem[off] = value
            if off == self.VTOR:
                self.on_vtor(value)
            elif (
                off == self.AIRCR
                and value & 0xFFFF_0004 == self.SYSRESETREQ
                and self.on_reset is not None
            ):
                self.on_reset()

    def read(self, off: int) -> int:
        if self.ICER <= off < self.ICER + 0x20:
            return self.mem.get(self.ISER + (off - self.ICER), 0)
        return self.mem.get(off, 0)

    def irq_enabled(self, irq: int) -> bool:
        return bool(self.mem.get(self.ISER + 4 * (irq // 32), 0) >> (irq % 32) & 1)

    def irq_priority(self, irq: int) -> int:
        word = self.mem.get(self.IPR + (irq & ~3), 0)
        return (word >> (8 * (irq & 3))) & 0xF0  # 4 bits implemented (PM0214 4.2.7)

    def systick_priority(self) -> int:
        return (self.mem.get(self.SHPR3, 0) >> 24) & 0xF0

    def systick_on(self) -> bool:
        return self.mem.get(self.SYST_CSR, 0) & 3 == 3

    def systick_period_clocks(self, hclk: int) -> float:
        csr = self.mem.get(self.SYST_CSR, 0)
        clocks = self.mem.get(self.SYST_RVR, 0) + 1
        return clocks / hclk if csr & 4 else clocks * 8 / hclk
