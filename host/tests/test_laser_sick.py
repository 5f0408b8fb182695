"""SICK TiM5xx / LMS1xx / LMS5xx: the CoLa codec against telegrams written from SICK's documents, and the driver
against the emulator over loopback TCP (every socket on 127.0.0.1, port 0)."""

from __future__ import annotations

import math
import socket
import threading
import time
from functools import reduce

import numpy as np
import pytest

from agnav_host.lasers import LaserAddressError, LaserUrlError, TelegramError, WrongDeviceError, open_laser
from agnav_host.lasers.sick import (
    DEVICE_CLOCK_WRAP_S,
    SOPAS_ERRORS,
    Deframer,
    ScanTelegram,
    SopasError,
    encode_command,
    encode_scandata,
    frame,
    parse_scandata,
    split_command,
    unframe,
    xor_checksum,
)
from agnav_host.sil.emulators.base import ScanGeometry
from agnav_host.sil.emulators.sick import SickEmulator


def hexb(text: str) -> bytes:
    return bytes.fromhex(" ".join(line.split("#")[0] for line in text.splitlines()))


# ---- framing: the vendor's own examples ---------------------------------------------------------------------

def test_framing_reproduces_the_vendor_examples():
    # LMS4000 operating instructions, table 13: sEN LMDscandata 1 in CoLa-A and CoLa-B
    en_b = encode_command("b", "sEN", "LMDscandata", ("u8", 1))
    assert frame(en_b, "b") == hexb("02 02 02 02 00 00 00 11 73 45 4E 20 4C 4D 44 73 63 61 6E 64 61 74 61 20 01 33")
    en_a = encode_command("a", "sEN", "LMDscandata", ("u8", 1))
    assert frame(en_a, "a") == hexb("02 73 45 4E 20 4C 4D 44 73 63 61 6E 64 61 74 61 20 31 03")
    # TiM781 / MRS1000 operating instructions: sRN LMDscandata, binary checksum 05
    assert frame(encode_command("b", "sRN", "LMDscandata"), "b") == hexb(
        "02 02 02 02 00 00 00 0F 73 52 4E 20 4C 4D 44 73 63 61 6E 64 61 74 61 05")
    # LMS4000 12.3.1.2.2: sMN SetAccessMode 03 F4724744, length 17h, checksum B3
    login = frame(encode_command("b", "sMN", "SetAccessMode", ("u8", 3), ("u32", 0xF4724744)), "b")
    assert login[4:8] == b"\x00\x00\x00\x17" and login[-1] == 0xB3
    assert login[8:-1] == b"sMN SetAccessMode \x03\xf4\x72\x47\x44"
    assert unframe(login) == ("b", login[8:-1])
    assert xor_checksum(b"sEA LMDscandata \x01") == 0x3C  # the manual's sEA example repeats the sEN checksum 33


def test_deframer_splits_both_encodings_from_one_byte_stream_in_any_chunks():
    stream = (frame(b"sEA LMDscandata 1", "a") + frame(b"sEA LMDscandata \x01", "b")
              + frame(b"sRA DeviceIdent \x00\x06TiM561\x00\x05V3.01", "b") + frame(b"sAN Run 1", "a"))
    d, got = Deframer(), []
    for i in range(len(stream)):
        d.feed(stream[i : i + 1])
        while (t := d.next()) is not None:
            got.append(t)
    assert [c for c, _ in got] == ["a", "b", "b", "a"]
    assert got[2][1].endswith(b"TiM561\x00\x05V3.01") and d.pending == b""


# ---- LMDscandata written by hand from the telegram listing / TiM5xx technical information ---------------------

# A TiM56x answer with 5 beams: DIST1 (16 bit) and RSSI1 (8 bit), device name on, as [TIM 5.3] lists the fields.
TIM_A = (b"sRA LMDscandata 1 1 10A3B5C 0 0 1C2 1C7 5F5E100 5F6A068 0 0 1 0 0 5DC A2 0 "
         b"1 DIST1 3F800000 00000000 FFF92230 D05 5 0 32 1F4 3E8 2710 "
         b"1 RSSI1 3F800000 00000000 FFF92230 D05 5 0 64 C8 FF 80 "
         b"0 1 C TiM561 front 0 0 0")

# The same telegram in CoLa-B, field by field
TIM_B_PAYLOAD = hexb("""
73 52 41 20 4C 4D 44 73 63 61 6E 64 61 74 61 20   # sRA LMDscandata + space
00 01                                             # version 1
00 01                                             # device number 1
01 0A 3B 5C                                       # serial number
00 00                                             # device status
01 C2                                             # telegram counter 450
01 C7                                             # scan counter 455
05 F5 E1 00                                       # time since start-up 100 000 000 us
05 F6 A0 68                                       # time of transmission 100 049 000 us
00 00                                             # inputs
01 00                                             # outputs
00 00                                             # reserved
00 00 05 DC                                       # scanning frequency 1500 (1/100 Hz)
00 00 00 A2                                       # measurement frequency 162 (x 100 Hz)
00 00                                             # no encoders
00 01                                             # one 16-bit channel
44 49 53 54 31                                    # DIST1
3F 80 00 00                                       # scale factor 1.0
00 00 00 00                                       # scale offset 0
FF F9 22 30                                       # start angle -450 000 (1/10 000 deg)
0D 05                                             # angular step 3333
00 05                                             # 5 values
00 00 00 32 01 F4 03 E8 27 10                     # 0, 50, 500, 1000, 10000 mm
00 01                                             # one 8-bit channel
52 53 53 49 31 3F 80 00 00 00 00 00 00 FF F9 22 30 0D 05 00 05   # RSSI1, same header
00 64 C8 FF 80                                    # RSSI values
00 00                                             # no position
00 01 00 0C 54 69 4D 35 36 31 20 66 72 6F 6E 74   # name: 12 characters "TiM561 front"
00 00 00 00 00 00                                 # no comment, no time, no event
""")
TIM_B = b"\x02\x02\x02\x02\x00\x00\x00\x8b" + TIM_B_PAYLOAD + b"\xc4"  # length 139, XOR C4 (worked out by hand)


def check_tim_fields(t: ScanTelegram, kind: str = "sRA") -> None:
    assert (t.version, t.device_number, t.serial_number, t.device_status) == (1, 1, 0x10A3B5C, (0, 0))
    assert (t.telegram_counter, t.scan_counter) == (450, 455)
    assert (t.time_since_startup_us, t.time_of_transmission_us) == (100_000_000, 100_049_000)
    assert (t.inputs, t.outputs, t.layer_angle) == ((0, 0), (1, 0), 0)
    assert (t.scan_frequency, t.scan_frequency_hz, t.measurement_frequency_hz) == (1500, 15.0, 16200.0)
    assert t.encoders == () and len(t.channels16) == 1 and len(t.channels8) == 1
    d = t.dist1
    assert (d.content, d.scale_factor, d.scale_offset) == ("DIST1", 1.0, 0.0)
    assert (d.start_angle, d.angular_step, d.start_angle_deg) == (-450000, 3333, -45.0)
    assert d.data.tolist() == [0, 50, 500, 1000, 10000]
    r = t.distances_m()
    assert math.isnan(r[0]) and r[1:].tolist() == [0.05, 0.5, 1.0, 10.0]
    rssi = t.channel("RSSI1")
    assert rssi is not None and rssi.data.tolist() == [0, 100, 200, 255, 128] and rssi.start_angle == -450000
    assert t.rssi() is not None and t.rssi().dtype == np.uint8  # type: ignore[union-attr]
    assert (t.position, t.device_name, t.comment, t.timestamp, t.event, t.kind) == (
        None, "TiM561 front", None, None, None, kind)


def test_cola_a_telegram_from_the_documents_parses_field_by_field():
    cola, payload = unframe(b"\x02" + TIM_A + b"\x03")
    assert cola == "a"
    check_tim_fields(parse_scandata(payload, cola))


def test_cola_b_telegram_from_the_documents_parses_field_by_field():
    assert len(TIM_B_PAYLOAD) == 0x8B and reduce(lambda a, c: a ^ c, TIM_B_PAYLOAD, 0) == 0xC4
    cola, payload = unframe(TIM_B)
    assert cola == "b"
    check_tim_fields(parse_scandata(payload, cola))


def test_the_encoder_writes_the_same_bytes_as_the_documents():
    t = parse_scandata(TIM_A, "a")
    assert encode_scandata(t, "a") == TIM_A
    assert encode_scandata(t, "b") == TIM_B_PAYLOAD


# Every optional block on: an encoder, two 16-bit channels with scale 2 and offset 0.5, position, comment, time
# and event info (an LMS5xx-style start angle of -5 deg at 0.5 deg steps).
FULL_A = (b"sSN LMDscandata 0 2 4D2 0 1 FFFF 10 +1000 +1002 3 0 0 0 0 1388 168 1 3E8 1F4 "
          b"2 DIST1 40000000 3F000000 FFFF3CB0 1388 3 0 64 FFFF "
          b"RSSI1 3F800000 00000000 FFFF3CB0 1388 3 10 20 30 0 "
          b"1 3F800000 40000000 40400000 00000000 00000000 3FC90FDB 3 0 1 8 row scan "
          b"1 7E8 5 1F C 2D 3B F423F 1 FDIN 64 5F5E100 15F90")


def test_every_optional_block_in_cola_a_and_b():
    t = parse_scandata(FULL_A, "a")
    assert (t.version, t.device_number, t.serial_number, t.device_status) == (0, 2, 1234, (0, 1))
    assert (t.telegram_counter, t.scan_counter, t.time_since_startup_us, t.time_of_transmission_us) == (
        0xFFFF, 16, 1000, 1002)  # decimal fields written with a sign
    assert (t.inputs, t.outputs, t.scan_frequency_hz, t.measurement_frequency_hz) == ((3, 0), (0, 0), 50.0, 36000.0)
    assert t.encoders == ((1000, 500),)
    d = t.dist1
    assert (d.scale_factor, d.scale_offset, d.start_angle_deg, d.angular_step_deg) == (2.0, 0.5, -5.0, 0.5)
    assert d.scaled().tolist() == [0.5, 200.5, 131070.5]
    assert np.isnan(t.distances_m()[0]) and t.distances_m()[1] == pytest.approx(0.2005)
    assert t.channels16[1].content == "RSSI1" and t.rssi().tolist() == [16, 32, 48]  # type: ignore[union-attr]
    assert t.channels8 == ()
    assert t.position == pytest.approx((1.0, 2.0, 3.0, 0.0, 0.0, math.pi / 2, 3))
    assert (t.device_name, t.comment) == (None, "row scan")
    assert t.timestamp == (2024, 5, 31, 12, 45, 59, 999999)
    assert t.event == ("FDIN", 100, 100_000_000, 90000)
    b = parse_scandata(encode_scandata(t, "b"), "b")
    assert encode_scandata(b, "a") == FULL_A.replace(b"+1000 +1002", b"3E8 3EA")
    assert (b.position, b.comment, b.timestamp, b.event, b.encoders) == (
        t.position, t.comment, t.timestamp, t.event, t.encoders)


# ---- what is wrong, said clearly ----------------------------------------------------------------------------

@pytest.mark.parametrize("payload, words", [
    (TIM_A[: TIM_A.index(b"3E8 2710")], "announces 5 values, the telegram ends after 3"),
    (TIM_A.replace(b"D05 5 0 32", b"D05 6 0 32", 1), "'number of 8-bit channels' is 'RSSI1'"),
    (TIM_A + b" 0", "1 bytes after the last field"),
    (TIM_A.replace(b"1C7", b"1G7"), "'scan counter' is '1G7', not a CoLa-A number"),
    (TIM_A.replace(b"1C2", b"12345"), "'telegram counter' = 12345h does not fit 16 bits"),
    (TIM_A.replace(b"DIST1", b"DIST"), "'16-bit channel 1 content' must have 5 characters"),
    (TIM_A.replace(b"1 C TiM561 front", b"1 A TiM561 front"), "announces 10 characters, but the text goes on"),
    (TIM_A.replace(b"sRA LMDscandata 1", b"sRA LMDscandata 2"), "version 2"),
    (TIM_A.replace(b"LMDscandata", b"LMDscandatb"), "expected sRA or sSN LMDscandata, got sRA LMDscandatb"),
    (TIM_A.replace(b"front 0 0 0", b"front 0 0 2"), "'event info' must be 0 or 1"),
    (b"sRA LMDscandata 1 1", "ends before 'serial number'"),
    (b"hello", "not a SOPAS command"),
])
def test_malformed_cola_a_telegrams_name_the_field(payload, words):
    with pytest.raises(TelegramError) as e:
        parse_scandata(payload, "a")
    assert words in str(e.value)


def test_malformed_cola_b_telegrams():
    with pytest.raises(TelegramError, match="checksum mismatch: the telegram says C5h, the XOR of its 139 payload "
                                            "bytes is C4h"):
        unframe(TIM_B[:-1] + b"\xc5")
    with pytest.raises(TelegramError, match="truncated CoLa-B"):
        unframe(TIM_B[:60])
    cut = TIM_B_PAYLOAD[:80]  # framed correctly, but the body stops inside the DIST1 data
    with pytest.raises(TelegramError, match=r"ends in '16-bit channel 1 data' \(needs 10 bytes at offset 61, 3 left"):
        parse_scandata(unframe(frame(cut, "b"))[1], "b")
    with pytest.raises(TelegramError, match="bytes after the last field"):
        parse_scandata(TIM_B_PAYLOAD + b"\x00", "b")
    with pytest.raises(TelegramError, match="length 4294967295"):
        unframe(b"\x02\x02\x02\x02\xff\xff\xff\xff" + b"x" * 8)
    with pytest.raises(TelegramError, match="bytes after the telegram"):
        unframe(TIM_B + b"\x02")


def test_bytes_outside_telegrams_and_cut_telegrams_are_reported_and_skipped():
    d = Deframer()
    d.feed(b"VV\n00P\n" + b"\x02sRA LMDscan" + b"\x02sAN Run 1\x03")
    with pytest.raises(TelegramError, match=r"7 bytes outside any CoLa telegram .*'VV\\n00P\\n'|7 bytes outside"):
        d.next()
    with pytest.raises(TelegramError, match="cut off"):
        d.next()
    assert d.next() == ("a", b"sAN Run 1")
    with pytest.raises(TelegramError, match="truncated CoLa-A"):
        unframe(b"\x02sRA LMDscandata 1 1")


@pytest.mark.parametrize("cola, payload, code, name", [
    ("a", b"sFA 3", 3, "Sopas_Error_VARIABLE_UNKNOWNINDEX"),
    ("a", b"sFA 11", 0x11, "Sopas_Error_COLA_A_INVALID_CHARACTER"),
    ("b", b"sFA\x00\x0b", 0xB, "Sopas_Error_UNKNOWN_CMD_FOR_NAMESERVER"),
    ("b", b"sFA\x00\x04", 4, "Sopas_Error_LOCALCONDITIONFAILED"),
])
def test_sfa_answers_raise_with_the_code_and_its_name(cola, payload, code, name):
    with pytest.raises(SopasError) as e:
        parse_scandata(payload, cola)
    assert e.value.code == code and e.value.name == name and name in str(e.value)
    assert f"sFA {code:X}h" in str(e.value) and SOPAS_ERRORS[code][0] == name
    assert isinstance(e.value, TelegramError)
    assert split_command(cola, payload).error_code() == code


# ---- the driver against the emulator ------------------------------------------------------------------------

TIM_GEOMETRY = ScanGeometry(math.radians(-135.0), math.radians(1 / 3), 811, 0.05, 10.0, 15.0)
LMS1_GEOMETRY = ScanGeometry(math.radians(-135.0), math.radians(0.5), 541, 0.5, 20.0, 50.0)
LMS5_GEOMETRY = ScanGeometry(math.radians(-95.0), math.radians(0.25), 761, 1.0, 80.0, 25.0)
GEOMETRY = {"tim5xx": TIM_GEOMETRY, "lms1xx": LMS1_GEOMETRY, "lms5xx": LMS5_GEOMETRY}


@pytest.fixture
def emulators():
    made: list[SickEmulator] = []

    def make(kind: str, geometry: ScanGeometry | None = None, **kw) -> SickEmulator:
        emu = SickEmulator(kind, geometry or GEOMETRY[kind], ports=(0, 0), **kw)
        emu.start()
        made.append(emu)
        return emu

    yield make
    for e in made:
        e.close()


@pytest.fixture
def lasers():
    made = []

    def make(url: str):
        laser = open_laser(url)
        made.append(laser)
        return laser

    yield make
    for laser in made:
        laser.close()


def test_emulator_ports_and_endpoints(emulators):
    tim = emulators("tim5xx")
    p = tim.ports[0]
    assert tim.ports == (p, p) and tim.start() == f"tcp:127.0.0.1:{p}"
    lms = emulators("lms1xx")
    a, b = lms.ports
    assert a != b and lms.start() == f"tcp:127.0.0.1:{a},tcp:127.0.0.1:{b}"


def ranges_for(g: ScanGeometry, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(g.range_min_m + 0.01, g.range_max_m - 0.01, g.n_beams)


@pytest.mark.parametrize("kind", ["tim5xx", "lms1xx", "lms5xx"])
@pytest.mark.parametrize("cola", ["a", "b"])
@pytest.mark.parametrize("mode", ["stream", "poll"])
def test_driver_reads_the_emulator(emulators, lasers, kind, cola, mode):
    g = GEOMETRY[kind]
    emu = emulators(kind)
    port = emu.ports[0 if cola == "a" else 1]
    laser = lasers(f"{kind}://127.0.0.1:{port}?cola={cola}&mode={mode}")
    info = laser.start(timeout_s=2.0)
    assert info.kind == kind and info.address == f"127.0.0.1:{port}" and info.stamps == "device"
    assert info.model == f"{emu.model} {emu.version}" and info.serial == str(emu.serial)
    for k in range(3):
        r = ranges_for(g, k)
        r[5], r[6] = np.nan, np.inf  # no return
        emu.publish(r, 2.0 + k / g.scan_hz)
        scan = laser.wait(2.0)
        assert scan is not None, laser.stats
        assert len(scan.ranges_m) == g.n_beams
        assert scan.angle_min_rad == pytest.approx(g.angle_min_rad, abs=1e-6)
        assert scan.angle_increment_rad == pytest.approx(g.angle_increment_rad, abs=1e-6)
        assert np.isnan(scan.ranges_m[5]) and np.isnan(scan.ranges_m[6])
        ok = np.isfinite(r)
        assert np.all(np.isfinite(scan.ranges_m[ok]))
        assert np.max(np.abs(scan.ranges_m[ok] - r[ok])) <= 0.0005 * emu.scale + 1e-9  # mm (LMS5xx: 2 mm) units
        assert scan.stamp_s <= time.monotonic()
    assert laser.info.scan_hz == pytest.approx(g.scan_hz)
    assert laser.stats.malformed == 0 and laser.stats.reconnects == 0


def test_no_echo_below_minimum_and_beyond_maximum_are_nan(emulators, lasers):
    emu = emulators("tim5xx")
    laser = lasers(f"tim5xx://127.0.0.1:{emu.ports[1]}")
    laser.start(2.0)
    r = np.full(TIM_GEOMETRY.n_beams, 3.0)
    r[:5] = [np.nan, np.inf, 0.01, 12.0, -1.0]
    emu.publish(r, 1.0)
    scan = laser.wait(2.0)
    assert scan is not None
    assert np.all(np.isnan(scan.ranges_m[:5])) and np.all(scan.ranges_m[5:] == 3.0)
    assert scan.range_max_m == 10.0 and not scan.valid_mask()[:5].any()


def test_driver_range_min_option_masks_near_returns(emulators, lasers):
    emu = emulators("tim5xx")
    laser = lasers(f"tim5xx://127.0.0.1:{emu.ports[1]}?range_min=0.5&range_max=8")
    laser.start(2.0)
    r = np.full(TIM_GEOMETRY.n_beams, 0.3)
    r[0] = 0.6
    emu.publish(r, 1.0)
    scan = laser.wait(2.0)
    assert scan is not None and scan.ranges_m[0] == 0.6 and np.all(np.isnan(scan.ranges_m[1:]))
    assert scan.range_max_m == 8.0


def test_lms5xx_beyond_65_m_uses_scale_factor_2(emulators, lasers):
    emu = emulators("lms5xx")
    r = np.full(LMS5_GEOMETRY.n_beams, 70.001)
    emu.publish(r, 1.0)
    tel = emu.telegram(emu.board.newest())  # type: ignore[arg-type]
    assert tel.dist1.scale_factor == 2.0 and tel.dist1.start_angle == -50000 and tel.dist1.angular_step == 2500
    laser = lasers(f"lms5xx://127.0.0.1:{emu.ports[1]}?mode=poll")
    laser.start(2.0)
    scan = laser.wait(2.0)
    assert scan is not None and np.allclose(scan.ranges_m, 70.001, atol=0.001)  # 2 mm units


def test_stamps_follow_the_device_clock_mapped_to_monotonic_time(emulators, lasers):
    emu = emulators("tim5xx")
    laser = lasers(f"tim5xx://127.0.0.1:{emu.ports[1]}")
    laser.start(2.0)
    stamps, arrivals = [], []
    for k in range(8):
        # simulated time runs slower than the wall clock (10 ms a scan, 40+ ms apart), so the first scan
        # fixes the clock offset and the stamps keep the device's spacing
        emu.publish(np.full(TIM_GEOMETRY.n_beams, 2.0), 5.0 + 0.01 * k)
        scan = laser.wait(2.0)
        assert scan is not None
        stamps.append(scan.stamp_s)
        arrivals.append(time.monotonic())
        time.sleep(0.04)
    assert np.allclose(np.diff(stamps), 0.01, atol=2e-6)
    assert all(s <= a for s, a in zip(stamps, arrivals))
    assert arrivals[0] - stamps[0] < 0.5  # on the host's monotonic clock, not the device's 15 s


def test_stamps_survive_the_32_bit_microsecond_wrap(emulators, lasers):
    emu = emulators("tim5xx", uptime_at_zero_s=DEVICE_CLOCK_WRAP_S - 0.01)
    laser = lasers(f"tim5xx://127.0.0.1:{emu.ports[1]}?cola=a")
    laser.start(2.0)
    stamps, starts = [], []
    for k in range(6):
        emu.publish(np.full(TIM_GEOMETRY.n_beams, 2.0), 0.01 * k)
        starts.append(emu.telegram(emu.board.newest()).time_since_startup_us)  # type: ignore[arg-type]
        scan = laser.wait(2.0)
        assert scan is not None
        stamps.append(scan.stamp_s)
        time.sleep(0.04)
    assert starts[-1] < starts[0], "the device counter wrapped during the test"
    assert np.allclose(np.diff(stamps), 0.01, atol=2e-6)


def test_reconnects_after_the_device_drops_the_connection(emulators, lasers):
    emu = emulators("lms1xx")
    laser = lasers(f"lms1xx://127.0.0.1:{emu.ports[1]}")
    laser.reconnect_delay_s = 0.05
    laser.start(2.0)
    emu.publish(np.full(LMS1_GEOMETRY.n_beams, 4.0), 1.0)
    assert laser.wait(2.0) is not None
    emu.drop_clients()
    deadline = time.monotonic() + 5.0
    k = 0
    while laser.stats.reconnects == 0 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert laser.stats.reconnects == 1, laser.stats
    got = None
    while got is None and time.monotonic() < deadline:
        k += 1
        emu.publish(np.full(LMS1_GEOMETRY.n_beams, 5.0), 1.0 + k * 0.02)
        got = laser.wait(0.2)
    assert got is not None and np.all(got.ranges_m == 5.0)
    assert laser.stats.reconnects == 1 and "closed the connection" in laser.stats.last_error


def test_a_closed_port_is_an_address_error(lasers):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    laser = lasers(f"tim5xx://127.0.0.1:{port}")
    with pytest.raises(LaserAddressError) as e:
        laser.start(timeout_s=1.0)
    text = str(e.value)
    assert f"127.0.0.1:{port}" in text and "refused" in text and "192.168.0.1" in text and "port" in text


class TextServer:
    """A TCP server on 127.0.0.1 that answers any request with fixed bytes (a device of another kind)."""

    def __init__(self, answer: bytes) -> None:
        self.answer = answer
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(1)
        self.srv.settimeout(3.0)
        self.port = self.srv.getsockname()[1]
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            conn, _ = self.srv.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(2.0)
            try:
                conn.recv(4096)
                conn.sendall(self.answer)
                conn.recv(4096)  # until the client goes
            except OSError:
                pass

    def close(self) -> None:
        self.srv.close()
        self.thread.join(3.0)


def test_a_scip_device_is_the_wrong_device(lasers):
    srv = TextServer(b"VV\n00P\nVEND:Hokuyo Automatic Co., Ltd.;[\nPROD:UST-10LX;Q\n\n")
    try:
        laser = lasers(f"tim5xx://127.0.0.1:{srv.port}")
        with pytest.raises(WrongDeviceError) as e:
            laser.start(timeout_s=2.0)
    finally:
        srv.close()
    assert "no SICK scanner speaking CoLa" in str(e.value) and "SCIP" in str(e.value) and "ust://" in str(e.value)


def test_a_binary_device_is_the_wrong_device(lasers):
    srv = TextServer(b"\xa5\x5a\x14\x00\x00\x00\x04\x18\x1d\x07")
    try:
        laser = lasers(f"lms5xx://127.0.0.1:{srv.port}")
        with pytest.raises(WrongDeviceError, match="RPLIDAR"):
            laser.start(timeout_s=2.0)
    finally:
        srv.close()


def test_a_tim5xx_url_on_an_lms5xx_is_the_wrong_device(emulators, lasers):
    emu = emulators("lms5xx")
    laser = lasers(f"tim5xx://127.0.0.1:{emu.ports[1]}")
    with pytest.raises(WrongDeviceError) as e:
        laser.start(timeout_s=2.0)
    text = str(e.value)
    assert "LMS511" in text and "'TiM5'" in text and f"lms5xx://127.0.0.1:{emu.ports[1]}" in text


def test_the_wrong_encoding_for_the_port_says_which_to_use(emulators, lasers):
    emu = emulators("lms1xx")
    laser = lasers(f"lms1xx://127.0.0.1:{emu.ports[0]}?cola=b")  # the CoLa-A port
    with pytest.raises(WrongDeviceError) as e:
        laser.start(timeout_s=2.0)
    assert "answered in CoLa-A to a CoLa-B request" in str(e.value) and "cola=a" in str(e.value)


@pytest.mark.parametrize("query, words", [
    ("cola=c", "cola must be a or b"),
    ("mode=fast", "mode must be stream or poll"),
    ("speed=1", "unknown option 'speed'"),
    ("range_min=-1", "range_min must be a distance"),
    ("range_min=5&range_max=2", "range_min < range_max"),
])
def test_bad_url_options(query, words):
    with pytest.raises(LaserUrlError, match=words):
        open_laser(f"tim5xx://192.0.2.1?{query}")


def test_mounting_pose_keys_in_the_url_are_left_to_agnav_run():
    laser = open_laser("lms1xx://192.0.2.1?cola=a&x=0.2&y=-0.1&yaw=5&pitch=0&height=0.4")
    assert laser.cola == "a"  # type: ignore[attr-defined]


# ---- the emulator answers as the device does ----------------------------------------------------------------

def exchange(port: int, cola: str, payload: bytes) -> tuple[str, bytes]:
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as s:
        s.sendall(frame(payload, cola))
        d = Deframer()
        while (t := d.next()) is None:
            d.feed(s.recv(4096))
        return t


def test_emulator_answers_unknown_and_refused_requests_with_sfa(emulators):
    tim = emulators("tim5xx")
    p = tim.ports[1]
    assert exchange(p, "a", b"sRN NoSuchVariable") == ("a", b"sFA B")
    assert exchange(p, "b", b"sRN NoSuchVariable") == ("b", b"sFA\x00\x0b")
    assert exchange(p, "a", b"sXX Something") == ("a", b"sFA C")
    assert exchange(p, "a", b"sMN LMCstartmeas") == ("a", b"sFA 1")  # needs the log-in
    assert exchange(p, "a", b"sEN LMDscandata 7") == ("a", b"sFA 4")
    assert exchange(p, "b", b"sEN LMDscandata") == ("b", b"sFA\x00\x08")  # the start/stop byte is missing
    assert exchange(p, "a", b"sMN SetAccessMode 03 F4724744") == ("a", b"sAN SetAccessMode 1")
    assert exchange(p, "a", b"sMN SetAccessMode 03 12345678") == ("a", b"sAN SetAccessMode 0")
    assert exchange(p, "a", b"sRN DeviceIdent") == ("a", b"sRA DeviceIdent 6 TiM561 5 V3.01")
    assert exchange(p, "b", b"sRN FirmwareVersion") == ("b", b"sRA FirmwareVersion \x00\x05V3.01")
    lms = emulators("lms1xx")
    assert exchange(lms.ports[0], "b", b"sRN DeviceIdent") == ("a", b"sFA 11")  # CoLa-B on the CoLa-A port
    assert exchange(lms.ports[1], "a", b"sRN DeviceIdent") == ("b", b"sFA\x00\x0c")


def test_emulator_streams_every_published_scan_to_several_clients_in_both_encodings(emulators):
    emu = emulators("tim5xx")
    socks = []
    try:
        for cola in ("a", "b"):
            s = socket.create_connection(("127.0.0.1", emu.ports[1]), timeout=2.0)
            s.sendall(frame(encode_command(cola, "sEN", "LMDscandata", ("u8", 1)), cola))
            socks.append((cola, s, Deframer()))
        for _cola, s, d in socks:
            while (t := d.next()) is None:
                d.feed(s.recv(4096))
            assert split_command(*t).kind == "sEA"
        for k in range(4):
            emu.publish(np.full(TIM_GEOMETRY.n_beams, 1.0 + k), 1.0 + k / 15)
        for cola, s, d in socks:
            got = []
            while len(got) < 4:
                t = d.next()
                if t is None:
                    d.feed(s.recv(65536))
                    continue
                assert t[0] == cola
                got.append(parse_scandata(t[1], cola))
            assert [g.scan_counter for g in got] == [1, 2, 3, 4]
            assert [g.dist1.data[0] for g in got] == [1000, 2000, 3000, 4000]
            assert all(g.kind == "sSN" and g.rssi() is not None for g in got)
            dt = np.diff([g.time_since_startup_us for g in got])
            assert np.all(np.abs(dt - 1e6 / 15) <= 1)
    finally:
        for _, s, _ in socks:
            s.close()
