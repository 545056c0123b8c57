"""Each peripheral model against the reference manual (RM0390; PM0214 for the core's), for every
register behaviour the port relies on. The models are driven through their registers as the
firmware drives them (read/write at offsets), and from the outside as the board's wiring does."""

from random import Random
from typing import Any

import pytest
from board import PWM_PERIOD, adc_code, current_ma, duty_of, pwm_counts
from hypothesis import given
from hypothesis import strategies as st
from periph import Adc, Flash, Gpio, I2c, Iwdg, Pwr, Rcc, Scs, Timer

from asserv import codec

S1 = 0x4000  # sector 1's offset from the flash's base: Flash.program() takes such offsets


# ---- RCC and PWR (RM0390 6.3.1, 6.3.2, 6.3.3, 5.1.4) -----------------------------------
def test_hse_ready_follows_hseon() -> None:
    r = Rcc(0)
    assert not r.read(r.CR) & r.HSERDY
    r.write(r.CR, r.read(r.CR) | r.HSEBYP | r.HSEON)
    assert r.read(r.CR) & r.HSERDY
    r.write(r.CR, r.read(r.CR) & ~r.HSEON)
    assert not r.read(r.CR) & r.HSERDY


def test_pll_locks_only_on_a_ready_source_and_takes_its_config_only_while_off() -> None:
    r = Rcc(0)
    r.write(r.PLLCFGR, 4 | 180 << 6 | 1 << 22)  # HSE source, HSE off
    r.write(r.CR, r.read(r.CR) | r.PLLON)
    assert not r.read(r.CR) & r.PLLRDY
    r.write(r.CR, r.read(r.CR) | r.HSEON | r.HSEBYP)
    assert r.read(r.CR) & r.PLLRDY
    r.write(r.PLLCFGR, 8 | 100 << 6 | 1 << 22)  # ignored: the PLL is on
    assert r.pll_hz() == 180_000_000


def test_sws_follows_sw_only_to_a_ready_source() -> None:
    r = Rcc(0)
    r.write(r.CFGR, 2)  # PLL, not ready
    assert (r.read(r.CFGR) >> 2) & 3 == 0
    assert r.sysclk_hz() == 16_000_000
    r.write(r.PLLCFGR, 4 | 180 << 6 | 1 << 22)
    r.write(r.CR, r.read(r.CR) | r.HSEON | r.HSEBYP | r.PLLON)
    r.write(r.CFGR, 2 | 5 << 10 | 4 << 13)
    assert (r.read(r.CFGR) >> 2) & 3 == 2
    assert r.sysclk_hz() == 180_000_000
    assert r.apb_div(1) == 4 and r.apb_div(2) == 2


def test_overdrive_switch_needs_overdrive_ready() -> None:
    p = Pwr(0)
    p.write(p.CR, p.ODSWEN)
    assert not p.read(p.CSR) & p.ODSWRDY
    p.write(p.CR, p.ODEN)
    assert p.read(p.CSR) & p.ODRDY and not p.overdrive()
    p.write(p.CR, p.ODEN | p.ODSWEN)
    assert p.overdrive()


# ---- GPIO (RM0390 7.4) ----------------------------------------------------------------
def test_idr_shows_pull_ups_driven_levels_and_outputs() -> None:
    g = Gpio(0)
    g.write(g.PUPDR, 1 << 2)  # pin 1 pulled up
    g.write(g.MODER, 1 << 4)  # pin 2 output
    assert g.read(g.IDR) & 0b111 == 0b010
    g.drive(1, 0)  # a switch to ground
    g.drive(0, 1)
    g.write(g.BSRR, 1 << 2)
    assert g.read(g.IDR) & 0b111 == 0b101
    g.drive(1, None)
    assert g.read(g.IDR) & 0b010


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF))
def test_bsrr_sets_resets_and_set_wins(odr: int, bsrr: int) -> None:
    g = Gpio(0)
    g.write(g.ODR, odr)
    g.write(g.BSRR, bsrr)
    want = (odr & ~(bsrr >> 16) | bsrr) & 0xFFFF
    assert g.read(g.ODR) == want
    assert g.read(g.BSRR) == 0


# ---- Timers: encoder mode (RM0390 17.3.16, Table 79) and PWM (16.3.10) -----------------
def encoder(ccer: int = 0, sms: int = 3, arr: int = 0xFFFF) -> Timer:
    t = Timer(0)
    t.write(t.ARR, arr)
    t.write(t.CCMR1, 1 | 1 << 8)
    t.write(t.CCER, ccer)
    t.write(t.SMCR, sms)
    t.write(t.CR1, 1)
    return t


def test_encoder_mode3_counts_every_edge_up_when_a_leads_b() -> None:
    t = encoder()
    for _ in range(8):
        t.quadrature_step(+1)
    assert t.read(t.CNT) == 8
    assert not t.read(t.CR1) & 0x10  # DIR: up
    t.quadrature_step(-1)
    assert t.read(t.CNT) == 7
    assert t.read(t.CR1) & 0x10  # DIR: down


def test_encoder_wraps_at_arr_both_ways() -> None:
    t = encoder(arr=0xFFFF)
    t.quadrature_step(-1)
    assert t.read(t.CNT) == 0xFFFF
    t.quadrature_step(+1)
    assert t.read(t.CNT) == 0


def test_encoder_cc1p_inverts_the_direction() -> None:
    t = encoder(ccer=1 << 1)
    for _ in range(4):
        t.quadrature_step(+1)
    assert t.read(t.CNT) == 0xFFFC


def test_encoder_mode1_counts_ti2_edges_only_and_nothing_when_stopped() -> None:
    t = encoder(sms=1)
    for _ in range(8):
        t.quadrature_step(+1)
    assert t.read(t.CNT) == 4
    t.write(t.CR1, 0)
    t.quadrature_step(+1)
    assert t.read(t.CNT) == 4


@given(
    st.integers(-3000, 3000),
    st.integers(0, 0xFFFF),
    st.integers(0, 3),
    st.sampled_from([0, 1 << 1, 1 << 5, 1 << 1 | 1 << 5]),
    st.sampled_from([1, 2, 3]),
)
def test_a_run_of_edges_counts_as_each_edge_would(
    n: int, cnt: int, phase: int, ccer: int, sms: int
) -> None:
    fast, slow = encoder(ccer, sms), encoder(ccer, sms)
    for t in (fast, slow):
        t.write(t.CNT, cnt)
        t.phase = phase
    fast.quadrature_move(n)
    for _ in range(abs(n)):
        slow.quadrature_step(1 if n > 0 else -1)
    assert (fast.read(fast.CNT), fast.phase) == (slow.read(slow.CNT), slow.phase)


def pwm_timer(preload: bool = True) -> Timer:
    t = Timer(0, advanced=True)
    t.write(t.ARR, PWM_PERIOD - 1)
    t.write(t.CCMR1, 6 << 4 | 6 << 12 | ((1 << 3 | 1 << 11) if preload else 0))
    t.write(t.CCER, 1 | 1 << 4)
    t.write(t.BDTR, 1 << 15)
    t.write(t.EGR, 1)
    t.write(t.CR1, 1 << 7 | 1)
    return t


def test_pwm_compare_is_preloaded_until_the_update_event() -> None:
    t = pwm_timer()
    t.write(t.CCR[0], 4500)
    assert t.pwm_fraction(0) == (0, PWM_PERIOD)
    t.update_event()
    assert t.pwm_fraction(0) == (4500, PWM_PERIOD)
    u = pwm_timer(preload=False)
    u.write(u.CCR[1], 100)
    assert u.pwm_fraction(1) == (100, PWM_PERIOD)


def test_pwm_needs_moe_cce_and_saturates_above_arr() -> None:
    t = pwm_timer(preload=False)
    t.write(t.CCR[0], PWM_PERIOD + 5)
    assert t.pwm_fraction(0) == (PWM_PERIOD, PWM_PERIOD)
    t.write(t.BDTR, 0)
    assert t.pwm_fraction(0)[0] == 0
    t.write(t.BDTR, 1 << 15)
    t.write(t.CCER, 1 << 4)
    assert t.pwm_fraction(0)[0] == 0


@given(st.integers(-32768, 32767))
def test_duty_through_the_pwm_is_the_nearest_step(d: int) -> None:
    counts = pwm_counts(d)
    assert 0 <= counts <= PWM_PERIOD
    got = duty_of(counts, PWM_PERIOD, 1 if d > 0 else -1 if d < 0 else 0)
    assert abs(got - d) <= 32768 / PWM_PERIOD / 2 + 1
    assert (got > 0) == (d > 0 and counts > 0)


@given(st.integers(-16000, 16000))
def test_current_sense_reads_within_one_code(ma: int) -> None:
    assert abs(current_ma(adc_code(ma)) - ma) <= 33000 / 4096 + 1


# ---- ADC (RM0390 13.3.8, 13.13.1, 13.13.12) -------------------------------------------
def test_injected_sequence_of_two_converts_jsq3_then_jsq4() -> None:
    a = Adc(0)
    a.codes = {4: 1111, 8: 2222, 1: 3333}
    a.write(a.JSQR, 1 << 20 | 4 << 10 | 8 << 15 | 1 << 5)
    a.write(a.CR2, a.ADON | a.JSWSTART)
    assert (a.read(a.JDR1), a.read(a.JDR1 + 4)) == (1111, 2222)
    assert a.read(a.SR) & (a.JEOC | a.JSTRT) == a.JEOC | a.JSTRT
    assert not a.read(a.CR2) & a.JSWSTART  # cleared by hardware


def test_injected_conversion_needs_adon_and_jeoc_clears_on_zero() -> None:
    a = Adc(0)
    a.codes = {4: 7}
    a.write(a.JSQR, 4 << 15)  # JL 0: JSQ4 alone into JDR1
    a.write(a.CR2, a.JSWSTART)
    assert a.read(a.SR) == 0
    a.write(a.CR2, a.ADON | a.JSWSTART)
    assert a.read(a.JDR1) == 7
    a.write(a.SR, 0xFFFFFFFF)  # rc_w0: ones change nothing
    assert a.read(a.SR) & a.JEOC
    a.write(a.SR, ~a.JEOC)
    assert not a.read(a.SR) & a.JEOC


# ---- I2C slave (RM0390 24.3.3, 24.3.8, 24.6) -------------------------------------------
def slave(cr2: int = I2c.ITEVTEN | I2c.ITERREN) -> I2c:
    i = I2c(0)
    i.write(i.CR2, 45 | cr2)
    i.write(i.OAR1, 1 << 14 | 2 << 1)
    i.write(i.CR1, i.PE)
    i.write(i.CR1, i.PE | i.ACK)
    return i


def test_address_match_sets_addr_and_raises_the_event_interrupt() -> None:
    i = slave()
    assert i.lines() == (False, False)
    assert i.start(2, False)
    assert i.sr1 & i.ADDR and i.lines() == (True, False)
    j = slave(cr2=0)
    assert j.start(2, False) and j.lines() == (False, False)
    k = slave()
    assert not k.start(5, False) and not k.sr1 & k.ADDR


def test_no_acknowledge_without_ack_and_ack_cleared_while_pe_is_off() -> None:
    i = slave()
    i.write(i.CR1, i.ACK)  # PE 0: ACK cleared
    assert not i.read(i.CR1) & i.ACK
    i.write(i.CR1, i.PE)
    assert not i.start(2, True)


def test_addr_clears_by_sr1_then_sr2_only() -> None:
    i = slave()
    i.start(2, True)
    assert i.read(i.SR2) & i.TRA
    assert i.sr1 & i.ADDR  # SR2 alone: still set
    i.read(i.SR1)
    i.read(i.SR2)
    assert not i.sr1 & i.ADDR
    assert i.sr1 & i.TXE  # a read: DR empty, to be written


def test_rxne_by_byte_cleared_by_dr_and_stopf_by_sr1_then_cr1() -> None:
    i = slave(cr2=I2c.ITEVTEN | I2c.ITBUFEN)
    i.start(2, False)
    i.read(i.SR1)
    i.read(i.SR2)
    i.write_byte(0x42)
    assert i.sr1 & i.RXNE and i.lines()[0]
    assert i.read(i.DR) == 0x42 and not i.sr1 & i.RXNE
    i.stop()
    assert i.sr1 & i.STOPF and i.lines()[0]
    i.write(i.CR1, i.read(i.CR1))  # CR1 written without SR1 read first: still set
    assert i.sr1 & i.STOPF
    i.read(i.SR1)
    i.write(i.CR1, i.read(i.CR1))
    assert not i.sr1 & i.STOPF and not i.lines()[0]


def test_unread_byte_holds_the_clock() -> None:
    i = slave()
    i.start(2, False)
    i.read(i.SR1)
    i.read(i.SR2)
    i.write_byte(1)
    try:
        i.write_byte(2)
    except RuntimeError:
        pass
    else:
        raise AssertionError("a second byte went in while DR was full")
    assert i.sr1 & i.BTF


def test_transmit_btf_on_ack_with_dr_empty_and_af_on_nack() -> None:
    i = slave()
    i.start(2, True)
    i.read(i.SR1)
    i.read(i.SR2)
    i.write(i.DR, 0x11)
    assert not i.sr1 & i.TXE
    assert i.read_byte_begin() == 0x11 and i.sr1 & i.TXE
    i.read_byte_end(True)
    assert i.sr1 & i.BTF and i.lines()[0]
    i.read(i.SR1)
    i.write(i.DR, 0x22)  # SR1 read then DR write: BTF cleared
    assert not i.sr1 & i.BTF
    assert i.read_byte_begin() == 0x22
    i.read_byte_end(False)
    assert i.sr1 & i.AF and i.lines() == (False, True)
    i.stop()
    assert not i.sr1 & i.STOPF  # the slave left at the NACK: no STOPF (Figure 245)
    i.write(i.SR1, 0xFFFF)  # rc_w0: ones leave AF
    assert i.sr1 & i.AF
    i.write(i.SR1, ~i.AF & 0xFFFF)
    assert not i.sr1 & i.AF and i.lines() == (False, False)


@given(st.lists(st.integers(0, 255), max_size=12), st.booleans())
def test_hardware_pec_is_the_smbus_crc8(data: list[int], read: bool) -> None:
    i = slave()
    i.write(i.CR1, i.PE | i.ACK | i.ENPEC)
    i.start(2, read)
    i.read(i.SR1)
    i.read(i.SR2)
    for b in data:
        if read:
            i.write(i.DR, b)
            i.read_byte_begin()
            i.read_byte_end(True)
        else:
            i.write_byte(b)
            i.read(i.DR)
    assert i.read(i.SR2) >> 8 == codec.crc8(bytes([4 | int(read), *data]))


# ---- Core peripherals (PM0214 4.2, 4.4, 4.5) -------------------------------------------
def test_nvic_enable_disable_and_four_priority_bits() -> None:
    s = Scs(lambda v: None)
    s._wr(None, 0x100 + 4, 4, 1 << 0, None)  # ISER1 bit 0: IRQ 32
    s._wr(None, 0x100, 4, 1 << 31, None)
    assert s.irq_enabled(31) and s.irq_enabled(32) and not s.irq_enabled(30)
    s._wr(None, 0x180, 4, 1 << 31, None)  # ICER0
    assert not s.irq_enabled(31) and s.irq_enabled(32)
    s._wr(None, 0x400 + 31, 1, 0x4F, None)  # a byte write to IPR
    assert s.irq_priority(31) == 0x40 and s.irq_priority(30) == 0


def test_systick_period_and_priority() -> None:
    seen: list[int] = []
    s: Any = Scs(seen.append)
    s.write(s.SYST_RVR, 179_999)
    s.write(s.SYST_CSR, 7)
    assert s.systick_on() and s.systick_period_clocks(180_000_000) == 1e-3
    s.write(s.SYST_CSR, 3)  # HCLK / 8
    assert s.systick_period_clocks(180_000_000) == 8e-3
    s.write(s.SHPR3, 0xF0 << 24)
    assert s.systick_priority() == 0xF0
    s.write(s.VTOR, 0x0800_0000)
    assert seen == [0x0800_0000]


# ---- Independent watchdog (RM0390 19.3, 19.4) ------------------------------------------
def test_watchdog_registers_need_the_access_key_and_reload_restarts_the_count() -> None:
    w = Iwdg(0)
    w.write(w.PR, 3)
    assert w.read(w.PR) == 0  # no 0x5555 first: ignored
    w.write(w.KR, 0xCCCC)
    w.write(w.KR, 0x5555)
    w.write(w.PR, 0)
    w.write(w.RLR, 479)
    w.write(w.KR, 0xAAAA)
    assert w.reload_ns() == 60e6
    w.write(w.RLR, 100)  # access closed by the reload key
    assert w.read(w.RLR) == 479
    w.advance(59_000_000)
    w.write(w.KR, 0xAAAA)
    w.advance(59_000_000)
    assert not w.expired
    w.advance(1_000_000)
    assert w.expired


def test_watchdog_counts_only_once_started() -> None:
    w = Iwdg(0)
    w.advance(10**12)
    assert not w.expired


# ---- Flash interface (RM0390 3.5, 3.8) ------------------------------------------------------
def unlocked_flash() -> Flash:
    fl = Flash(0)
    fl.write(fl.KEYR, fl.KEY1)
    fl.write(fl.KEYR, fl.KEY2)
    return fl


def test_flash_cr_is_locked_at_reset_and_opened_by_key1_then_key2() -> None:
    fl = Flash(0)
    assert fl.read(fl.CR) & fl.LOCK
    fl.write(fl.CR, fl.PG)  # ignored while locked
    assert fl.read(fl.CR) == fl.LOCK
    fl.write(fl.KEYR, fl.KEY1)
    assert fl.read(fl.CR) & fl.LOCK  # one key is not enough
    fl.write(fl.KEYR, fl.KEY2)
    assert not fl.read(fl.CR) & fl.LOCK
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    assert fl.read(fl.CR) == fl.PG | 2 << fl.PSIZE_POS
    fl.write(fl.CR, fl.LOCK)  # locked again by software
    assert fl.read(fl.CR) == fl.LOCK and not fl.faults


@given(st.integers(0, 0xFFFFFFFF), st.booleans())
def test_a_wrong_key_is_a_bus_error_and_locks_until_reset(key: int, first: bool) -> None:
    fl = Flash(0)
    if not first:
        fl.write(fl.KEYR, fl.KEY1)
    if key == (fl.KEY1 if first else fl.KEY2):
        return
    fl.write(fl.KEYR, key)
    assert fl.faults and "bus error" in fl.faults[0]
    fl.write(fl.KEYR, fl.KEY1)
    fl.write(fl.KEYR, fl.KEY2)
    assert fl.read(fl.CR) & fl.LOCK  # the right keys no longer open it
    fl.mem.clear()
    fl.reset_values()  # until the next reset
    fl.write(fl.KEYR, fl.KEY1)
    fl.write(fl.KEYR, fl.KEY2)
    assert not fl.read(fl.CR) & fl.LOCK


def test_a_key_while_unlocked_is_a_bus_error() -> None:
    fl = unlocked_flash()
    fl.write(fl.KEYR, fl.KEY1)
    assert fl.faults


def test_word_program_is_busy_for_its_time_then_written() -> None:
    fl = unlocked_flash()
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    fl.program(S1 + 16, 4, 0x1234_5678)
    assert fl.read(fl.SR) & fl.BSY and fl.data[16:20] == b"\xff" * 4  # not yet
    fl.advance(fl.PROGRAM_NS - 1)
    assert fl.read(fl.SR) & fl.BSY
    fl.advance(1)
    assert not fl.read(fl.SR) & fl.BSY
    assert fl.data[16:20] == bytes([0x78, 0x56, 0x34, 0x12])  # little-endian
    assert not fl.read(fl.SR) & fl.EOP  # EOP only with EOPIE
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS | fl.EOPIE)
    fl.program(S1 + 20, 4, 0)
    fl.advance(fl.PROGRAM_NS)
    assert fl.read(fl.SR) & fl.EOP
    fl.write(fl.SR, fl.EOP)  # rc_w1
    assert not fl.read(fl.SR) & fl.EOP


@given(st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFFFFFF))
def test_programming_only_clears_bits(old: int, new: int) -> None:
    fl = unlocked_flash()
    fl.data[0:4] = old.to_bytes(4, "little")
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    fl.program(S1 + 0, 4, new)
    fl.advance(fl.PROGRAM_NS)
    assert int.from_bytes(fl.data[0:4], "little") == old & new


@pytest.mark.parametrize(
    ("cr", "offset", "size", "flag"),
    [
        (2 << 8, 0, 4, Flash.PGSERR),  # no PG
        (Flash.PG | 2 << 8, 0, 2, Flash.PGPERR),  # a half-word at x32
        (Flash.PG | 0 << 8, 0, 4, Flash.PGPERR),  # a word at x8
        (Flash.PG | 1 << 8, 1, 2, Flash.PGAERR),  # a half-word not aligned
    ],
)
def test_a_bad_program_sets_its_error_and_writes_nothing(
    cr: int, offset: int, size: int, flag: int
) -> None:
    fl = unlocked_flash()
    fl.write(fl.CR, cr)
    fl.program(S1 + offset, size, 0)
    assert fl.read(fl.SR) & fl.ERRORS == flag and not fl.busy()
    assert fl.data[:8] == b"\xff" * 8
    fl.write(fl.SR, flag)  # rc_w1
    assert not fl.read(fl.SR) & fl.ERRORS


@pytest.mark.parametrize(
    ("sector", "psize", "ms"),
    [(1, 0, 400), (1, 1, 300), (1, 2, 250), (7, 0, 2000), (7, 1, 1300), (7, 2, 1000)],
)
def test_sector_erase_sets_ff_after_its_time_and_strt_reads_until_then(
    sector: int, psize: int, ms: int
) -> None:
    fl = unlocked_flash()
    mine, other = (fl.data, fl.data_b) if sector == 1 else (fl.data_b, fl.data)
    mine[:4] = bytes(4)
    other[:4] = bytes(4)
    fl.write(fl.CR, fl.SER | sector << fl.SNB_POS | psize << fl.PSIZE_POS)
    assert not fl.busy()  # SER alone does not start it
    fl.write(fl.CR, fl.read(fl.CR) | fl.STRT)
    assert fl.read(fl.SR) & fl.BSY and fl.read(fl.CR) & fl.STRT
    fl.advance(ms * 1_000_000 - 1)
    assert fl.busy() and mine[:4] == bytes(4)
    fl.advance(1)
    assert not fl.read(fl.SR) & fl.BSY and not fl.read(fl.CR) & fl.STRT
    assert mine == b"\xff" * len(mine)
    assert other[:4] == bytes(4) and other[4:] == b"\xff" * (len(other) - 4)  # the other kept
    assert fl.erased == [sector]


def test_sector_7_programs_at_its_offsets() -> None:
    fl = unlocked_flash()
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    fl.program(0x6_0000 + 8, 4, 0)
    fl.advance(fl.PROGRAM_NS)
    assert fl.data_b[8:12] == bytes(4) and fl.data == b"\xff" * len(fl.data)
    assert fl._array_rd(None, 8, 4, 0x6_0000) == 0


@pytest.mark.parametrize(
    "cr",
    [Flash.SER | 2 << 3, Flash.SER | 0 << 3, Flash.SER | 5 << 3, Flash.SER | 6 << 3, Flash.MER],
)
def test_erasing_the_code_is_a_fault(cr: int) -> None:
    fl = unlocked_flash()
    fl.write(fl.CR, cr | 2 << fl.PSIZE_POS | fl.STRT)
    assert fl.faults and not fl.busy()


def test_the_bus_stalls_on_the_sector_and_cr_while_busy() -> None:
    fl = unlocked_flash()
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    fl.program(S1 + 0, 4, 0)
    fl.advance(6_000)
    assert fl._array_rd(None, 0, 4, S1) == 0  # the read waited for the program's end
    assert fl.stalled_ns == fl.PROGRAM_NS - 6_000 and not fl.busy()
    fl.program(S1 + 4, 4, 0)
    fl.write(fl.CR, fl.LOCK)  # waits too, then locks
    assert fl.stalled_ns == 2 * fl.PROGRAM_NS - 6_000 and fl.data[4:8] == bytes(4)
    fl2 = unlocked_flash()
    fl2.write(fl2.CR, fl2.PG | 2 << fl2.PSIZE_POS)
    fl2.program(S1 + 0, 4, 0)
    assert fl2.read(fl2.SR) & fl2.BSY  # a register read does not wait...
    fl2.stall_on_sr = True
    assert not fl2.read(fl2.SR) & fl2.BSY  # ...but the CPU's load of it, fetched from flash


@given(st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFFFFFF), st.integers(0, 2**32 - 1))
def test_a_cut_program_leaves_a_part_of_its_changes(old: int, new: int, seed: int) -> None:
    fl = unlocked_flash()
    fl.data[0:4] = old.to_bytes(4, "little")
    fl.write(fl.CR, fl.PG | 2 << fl.PSIZE_POS)
    fl.program(S1 + 0, 4, new)
    fl.cut(Random(seed))
    got = int.from_bytes(fl.data[0:4], "little")
    assert got & ~old == 0  # no bit went from 0 to 1
    assert (old & new) & ~got == 0  # every bit is between the old word and the programmed one
    assert not fl.busy()


@given(st.binary(min_size=16, max_size=16), st.integers(0, 2**32 - 1))
def test_a_cut_erase_leaves_a_part_of_its_changes(old: bytes, seed: int) -> None:
    fl = unlocked_flash()
    fl.data[:16] = old
    fl.write(fl.CR, fl.SER | 1 << fl.SNB_POS | 2 << fl.PSIZE_POS | fl.STRT)
    fl.cut(Random(seed))
    for a, b in zip(old, fl.data[:16], strict=True):
        assert a & ~b == 0  # erasing only sets bits
    assert fl.data[16:] == b"\xff" * (len(fl.data) - 16)
