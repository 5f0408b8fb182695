"""The RPLIDAR A1/A2 codec, driver and emulator.

Codec tests use packets written by hand from the tables of Slamtec's "RPLIDAR Interface Protocol and
Application Notes" (A1 & A2): the response descriptors of Figures 4-4, 4-16, 4-19 and 4-21, the GET_INFO,
GET_HEALTH and GET_SAMPLERATE payloads, and the bit layout of the 5-byte sample (Figure 4-4). Driver tests
run against the emulator over a pty. The dropped device is a udev-style symlink: the driver opens
``tmp/ttyRPLIDAR`` -> emulator 1's pty; the test points the link at emulator 2 and closes emulator 1, which
makes the driver's read raise ``SerialException`` exactly as an unplugged USB adapter does, and the one
reconnect the driver then makes lands on emulator 2.
"""

from __future__ import annotations

import math
import os
import threading
import time

import numpy as np
import pytest

from agnav_host.lasers import (
    LaserAddressError,
    LaserError,
    LaserUrlError,
    TelegramError,
    WrongDeviceError,
    open_laser,
    parse_laser_url,
)
from agnav_host.lasers.rplidar import (
    CMD_EXPRESS_SCAN,
    CMD_GET_HEALTH,
    CMD_GET_INFO,
    CMD_SET_MOTOR_PWM,
    CMD_STOP,
    DESCRIPTOR_HEALTH,
    DESCRIPTOR_INFO,
    DESCRIPTOR_SAMPLERATE,
    DESCRIPTOR_SCAN,
    Descriptor,
    Health,
    RevolutionAssembler,
    RplidarScanner,
    SampleBlock,
    SampleStream,
    _open_error,
    describe_bytes,
    encode_descriptor,
    encode_sample,
    expect_descriptor,
    parse_descriptor,
    parse_health,
    parse_info,
    parse_sample,
    parse_samplerate,
    request,
    resample,
    split_requests,
)
from agnav_host.sil.emulators.base import ScanGeometry, Transport
from agnav_host.sil.emulators.rplidar import RplidarEmulator

HZ = 20.0
FULL = ScanGeometry(-math.pi, math.radians(1.0), 360, range_min_m=0.1, range_max_m=10.0, scan_hz=HZ)
Q = 0.125e-3 + 1e-9  # half of distance_q2's 0.25 mm step, m


# ---- codec: requests ---------------------------------------------------------------------------------------
def test_requests_without_and_with_payload():
    assert request(CMD_STOP) == bytes.fromhex("A5 25")
    assert request(CMD_GET_INFO) == bytes.fromhex("A5 50")
    assert request(CMD_GET_HEALTH) == bytes.fromhex("A5 52")
    # SET_MOTOR_PWM 660 = 0x0294: A5 F0 02 94 02, checksum A5^F0^02^94^02 = C1
    assert request(CMD_SET_MOTOR_PWM, bytes.fromhex("94 02")) == bytes.fromhex("A5 F0 02 94 02 C1")
    # EXPRESS_SCAN with its 5-byte payload of zeros: A5^82^05 = 22
    assert request(CMD_EXPRESS_SCAN, bytes(5)) == bytes.fromhex("A5 82 05 00 00 00 00 00 22")


def test_split_requests_on_the_device_side():
    buf = bytearray(b"\x00junk" + bytes.fromhex("A5 25 A5 F0 02 94 02 C1 A5 F0 02 94 02 00 A5 52 A5"))
    got = split_requests(buf)
    # the PWM request with a wrong checksum (00) is dropped, the trailing A5 waits for its command byte
    assert got == [(0x25, b""), (0xF0, bytes.fromhex("94 02")), (0x52, b"")]
    assert buf == bytearray(b"\xa5")
    buf += b"\x50"
    assert split_requests(buf) == [(0x50, b"")] and not buf


# ---- codec: descriptors and single answers ---------------------------------------------------------------
@pytest.mark.parametrize("raw, want", [
    ("A5 5A 05 00 00 40 81", Descriptor(5, 1, 0x81)),  # SCAN / FORCE_SCAN, Figure 4-4
    ("A5 5A 14 00 00 00 04", Descriptor(20, 0, 0x04)),  # GET_INFO, Figure 4-16
    ("A5 5A 03 00 00 00 06", Descriptor(3, 0, 0x06)),  # GET_HEALTH, Figure 4-19
    ("A5 5A 04 00 00 00 15", Descriptor(4, 0, 0x15)),  # GET_SAMPLERATE, Figure 4-21
])
def test_descriptors_from_the_document(raw, want):
    data = bytes.fromhex(raw)
    assert parse_descriptor(data) == want
    assert encode_descriptor(want) == data
    assert {DESCRIPTOR_SCAN, DESCRIPTOR_INFO, DESCRIPTOR_HEALTH, DESCRIPTOR_SAMPLERATE} >= {want}


def test_descriptor_errors():
    with pytest.raises(TelegramError, match="truncated"):
        parse_descriptor(bytes.fromhex("A5 5A 05 00"))
    with pytest.raises(TelegramError, match="A5 5A"):
        parse_descriptor(b"$GPGGA,1")
    with pytest.raises(TelegramError, match="mismatch.*20 bytes, single, type 0x04.*3 bytes, single, type 0x06"):
        expect_descriptor(bytes.fromhex("A5 5A 03 00 00 00 06"), DESCRIPTOR_INFO, "GET_INFO")


def test_get_info_answer():
    # model 0x18, firmware minor 29 (0x1D), major 1, hardware 7, serialnumber[0..15] = 00 .. 0F
    raw = bytes.fromhex("18 1D 01 07") + bytes(range(16))
    info = parse_info(raw)
    assert (info.model, info.firmware, info.hardware) == (0x18, (1, 29), 7)
    assert info.serial_hex == "000102030405060708090A0B0C0D0E0F"  # least significant byte printed first
    assert info.series == "A1" and info.describe() == "RPLIDAR A1 (model 0x18), firmware 1.29, hardware 7"
    with pytest.raises(TelegramError, match="truncated"):
        parse_info(raw[:19])


def test_get_health_answer():
    assert parse_health(bytes.fromhex("00 00 00")) == Health(0, 0)
    h = parse_health(bytes.fromhex("02 01 80"))  # error_code[7:0] = 01, error_code[15:8] = 80
    assert h.status == 2 and h.error_code == 0x8001 and "protection stop" in h.name
    with pytest.raises(TelegramError, match="status"):
        parse_health(bytes.fromhex("03 00 00"))
    with pytest.raises(TelegramError, match="truncated"):
        parse_health(b"\x00\x00")


def test_get_samplerate_answer():
    s = parse_samplerate(bytes.fromhex("FC 01 FE 00"))  # 0x01FC = 508 us, 0x00FE = 254 us
    assert (s.t_standard_us, s.t_express_us) == (508, 254)


# ---- codec: samples (Figure 4-4: byte 0 = quality<<2 | !S<<1 | S; byte 1 = angle_q6[6:0]<<1 | C) -------------
@pytest.mark.parametrize("raw, start, quality, angle_deg, dist_mm", [
    # quality 47, S=1 -> 47<<2 | 0b01 = BD; 90 deg = q6 5760 = 0x1680 -> byte 1 = 0x00<<1 | 1, byte 2 = 0x2D;
    # 1000.25 mm = q2 4001 = 0x0FA1
    ("BD 01 2D A1 0F", True, 47, 90.0, 1000.25),
    # quality 0, S=0 -> 0b10; q6 23039 = 0x59FF -> (0x7F<<1)|1 = FF, 0x59FF>>7 = B3; distance 0 (invalid)
    ("02 FF B3 00 00", False, 0, 23039 / 64, 0.0),
    # quality 15, S=0 -> 15<<2 | 0b10 = 3E; q6 1 -> 03 00; q2 65535 = 16383.75 mm
    ("3E 03 00 FF FF", False, 15, 1 / 64, 16383.75),
])
def test_samples_by_hand(raw, start, quality, angle_deg, dist_mm):
    data = bytes.fromhex(raw)
    s = parse_sample(data)
    assert (s.start, s.quality, s.angle_deg, s.distance_mm) == (start, quality, angle_deg, dist_mm)
    assert encode_sample(s.start, s.quality, s.angle_q6, s.distance_q2) == data


@pytest.mark.parametrize("raw, why", [
    ("BF 01 2D A1 0F", "start flag"),  # S = !S = 1
    ("BC 01 2D A1 0F", "start flag"),  # S = !S = 0
    ("BD 00 2D A1 0F", "check bit"),  # C = 0
    ("BD 01 B4 A1 0F", "not below 360"),  # q6 = 0xB4 << 7 = 23040
    ("BD 01 2D A1", "truncated"),
])
def test_bad_samples(raw, why):
    with pytest.raises(TelegramError, match=why):
        parse_sample(bytes.fromhex(raw))


def _samples(n, start_at=0):
    return [encode_sample(i == start_at, 47, (i * 64) % 23040, 4000 + i) for i in range(n)]


def test_resync_after_garbage_between_samples():
    s = _samples(6)
    garbage = bytes.fromhex("00 13 37 FF")
    data = s[0] + s[1] + garbage + b"".join(s[2:])
    whole = SampleStream().feed(data)
    assert [x.distance_q2 for x in whole.samples()] == [4000 + i for i in range(6)]
    st = SampleStream()
    got = []
    for i in range(len(data)):  # byte by byte: the same result
        got += st.feed(data[i:i + 1]).samples()
    assert [parse_sample(b) for b in s] == got
    assert (st.resyncs, st.skipped, st.synced) == (1, len(garbage), True)


def test_resync_from_an_unaligned_start_and_waiting_for_confirmation():
    s = _samples(5)
    st = SampleStream(synced=False)
    assert len(st.feed(s[0][2:] + s[1] + s[2])) == 0  # two samples: not yet confirmed (3 needed)
    got = st.feed(s[3] + s[4]).samples()
    assert [g.distance_q2 for g in got] == [4001, 4002, 4003, 4004] and st.skipped == 3
    assert len(st.feed(s[0][:3])) == 0 and len(st.feed(s[0][3:])) == 1  # a partial sample waits


def test_revolutions_split_at_the_start_flag():
    def block(starts, q6):
        n = len(q6)
        return SampleBlock(np.asarray(starts, bool), np.full(n, 47, np.uint8), np.asarray(q6), np.full(n, 4000))
    asm = RevolutionAssembler(min_samples=3)
    assert asm.push(block([0, 0], [100, 200]), 1.0) == []  # before the first S = 1: dropped
    assert asm.push(block([1, 0, 0], [0, 64, 128]), 2.0) == []
    revs = asm.push(block([0, 1, 0], [192, 0, 64]), 3.0)
    assert len(revs) == 1 and revs[0].angle_q6.tolist() == [0, 64, 128, 192]
    assert (revs[0].t_first_s, revs[0].t_last_s) == (2.0, 3.0)
    assert asm.push(block([1, 1], [0, 0]), 4.0) == []  # a 2-sample "revolution" is below min_samples


def test_resample_nearest_valid_sample_within_half_a_step():
    # headings (clockwise, deg): 0 -> beam angle 0; 10.3 and 9.9 -> both nearest to -10 (9.9 is nearer);
    # 20.2 has no return and is nearer to -20 than the valid 19.6; 30 is below range_min
    q6 = np.rint(np.array([0.0, 10.3, 9.9, 20.2, 19.6, 30.0]) * 64).astype(int)
    d2 = np.array([4000, 8000, 12000, 0, 16000, 100])
    r = resample(q6, d2, 360, 0.15, 12.0)
    beam = lambda deg: int(round(deg + 180)) % 360  # noqa: E731
    assert r[beam(0)] == 1.0 and r[beam(-10)] == 3.0 and r[beam(-20)] == 4.0
    assert np.isnan(r[beam(-30)]) and np.isnan(r[beam(-11)]) and np.count_nonzero(~np.isnan(r)) == 3


def test_describe_what_came_back():
    assert "NMEA" in describe_bytes(b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n")
    assert "boot text" in describe_bytes(b"RP LIDAR System.\r\nFirmware Ver 1.29 - rc1, HW Ver 7\r\n")
    assert describe_bytes(bytes(range(200, 230))).startswith("bytes c8 c9")


def test_url_options():
    with pytest.raises(LaserUrlError, match="beams"):
        open_laser("rplidar:/dev/ttyUSB0?beams=0")
    with pytest.raises(LaserUrlError, match="unknown option 'baudrate'"):
        open_laser("rplidar:/dev/ttyUSB0?baudrate=115200")
    s = open_laser("rplidar:/dev/ttyUSB0?baud=256000&beams=720&range_max=16&x=0.2&yaw=180")  # x, yaw: the mount
    assert isinstance(s, RplidarScanner) and (s.baud, s.beams, s.range_max_m) == (256000, 720, 16.0)
    assert s.latency_s == pytest.approx(50 / 256000 + 0.001)


def test_open_errors_name_the_port_and_the_fix():
    e = _open_error("/dev/ttyUSB0", OSError(13, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied"))
    assert isinstance(e, LaserAddressError) and "/dev/ttyUSB0" in str(e) and "dialout" in str(e)


# ---- the emulator on its own -----------------------------------------------------------------------------------
@pytest.fixture
def emulator():
    made = []

    def make(geometry=FULL, **kw):
        emu = RplidarEmulator("rplidar", geometry, **kw)
        made.append(emu)
        return emu, emu.start()

    yield make
    for emu in made:
        emu.close()


class Publisher:
    """Publishes ``ranges`` to the emulators in ``targets`` at the geometry's rate until stopped."""

    def __init__(self, targets, ranges):
        self.targets, self.ranges = targets, ranges
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        t = 0.0
        while not self._stop.is_set():
            for emu, ranges in zip(list(self.targets), list(self.ranges)):
                emu.publish(ranges, t)
            t += 1.0 / HZ
            self._stop.wait(1.0 / HZ)

    def stop(self):
        self._stop.set()
        self._t.join(2.0)


def _raw(path):
    import serial

    return serial.Serial(path, 115200, timeout=0.5)


def test_emulator_answers_as_the_device(emulator):
    emu, path = emulator()
    with _raw(path) as port:
        port.write(request(CMD_GET_INFO))
        assert port.read(27) == bytes.fromhex("A5 5A 14 00 00 00 04 18 1D 01 07") + emu.info.serial
        port.write(request(0x77) + request(CMD_SET_MOTOR_PWM, b"\x94\x02"))  # unknown / A2-only: ignored
        port.write(request(CMD_GET_HEALTH))
        assert port.read(10) == bytes.fromhex("A5 5A 03 00 00 00 06 00 00 00")
        port.write(request(0x59))
        assert port.read(11) == bytes.fromhex("A5 5A 04 00 00 00 15") + bytes.fromhex("8B 00 8B 00")  # 139 us
        port.write(request(0x40))  # RESET: the boot text
        assert port.read_until(b"Model: 18\r\n").startswith(b"RP LIDAR System.\r\nFirmware Ver 1.29")


def test_emulator_streams_a_partial_revolution_clockwise(emulator):
    g = ScanGeometry(math.radians(-135), math.radians(0.5), 541, 0.1, 10.0, HZ)  # a 270-degree scanner
    emu, path = emulator(g, pace=False)
    ranges = np.full(541, 2.0)
    ranges[270] = np.nan  # the forward beam: no return
    emu.publish(ranges, 0.0)
    with _raw(path) as port:
        port.write(request(0x20))
        assert port.read(7) == bytes.fromhex("A5 5A 05 00 00 40 81")
        got = SampleStream().feed(port.read(541 * 5)).samples()
    assert len(got) == 541 and got[0].start and not any(s.start for s in got[1:])
    heading = np.array([s.angle_deg for s in got])
    assert heading[0] == 0.0 and np.all(np.diff(heading) > 0)  # the device's turn: heading upwards
    assert not np.any((heading > 135) & (heading < 225))  # the 90 degrees behind are not sent
    assert got[0].distance_q2 == 0 and got[0].quality == 0  # heading 0 = beam 270, no return
    assert got[1].distance_q2 == 8000 and got[1].quality == 47 and got[1].angle_deg == 0.5  # beam 269 (-0.5 deg)


# ---- the driver against the emulator ------------------------------------------------------------------------
def _scans(src, n, timeout_s=3.0):
    out = []
    end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < end:
        s = src.wait(0.5)
        if s is not None:
            out.append((s, time.monotonic()))
    assert len(out) == n, f"got {len(out)} of {n} scans; stats {src.stats}"
    return out


def test_driver_reads_revolutions_as_scans(emulator):
    emu, path = emulator()
    rng = np.random.default_rng(7)
    ranges = rng.uniform(0.3, 9.5, 360)
    ranges[::9] = np.nan
    ranges[5] = np.inf
    pub = Publisher([emu], [ranges])
    src = open_laser(parse_laser_url(f"rplidar:{path}"))
    try:
        info = src.start()
        assert info.kind == "rplidar" and info.address == path and info.stamps == "arrival"
        assert info.model == "RPLIDAR A1 (model 0x18), firmware 1.29, hardware 7"
        assert info.serial == emu.info.serial_hex and info.latency_s == pytest.approx(50 / 115200 + 0.001)
        assert src.sample_time_s == pytest.approx(139e-6)
        scans = _scans(src, 6)
    finally:
        src.close()
        pub.stop()
    for s, got_at in scans:
        assert s.angle_min_rad == -math.pi and s.angle_increment_rad == pytest.approx(math.radians(1.0))
        assert s.full_circle and s.range_max_m == 12.0
        none = ~np.isfinite(ranges)
        assert np.array_equal(np.isnan(s.ranges_m), none)
        assert np.max(np.abs(s.ranges_m[~none] - ranges[~none])) <= Q
        assert s.stamp_s < got_at - info.latency_s
    stamps = np.array([s.stamp_s for s, _ in scans])
    assert np.all(np.diff(stamps) > 0) and 0.6 / HZ < np.mean(np.diff(stamps)) < 1.8 / HZ
    assert src.stats.malformed == 0 and src.stats.reconnects == 0


def test_driver_grid_and_a_partial_field(emulator):
    fine = ScanGeometry(-math.pi, math.radians(0.5), 720, 0.1, 10.0, HZ)
    wide = ScanGeometry(math.radians(-135), math.radians(0.5), 541, 0.1, 10.0, HZ)
    emu1, path1 = emulator(fine)
    emu2, path2 = emulator(wide)
    r1 = np.linspace(0.5, 9.0, 720)
    r2 = np.linspace(1.0, 3.0, 541)
    pub = Publisher([emu1, emu2], [r1, r2])
    a = open_laser(f"rplidar:{path1}")  # 360 beams of 1 deg from 720 samples of 0.5 deg
    b = open_laser(f"rplidar:{path2}?beams=720")
    try:
        a.start()
        b.start()
        sa, _ = _scans(a, 2)[-1]
        sb, _ = _scans(b, 2)[-1]
    finally:
        a.close()
        b.close()
        pub.stop()
    assert len(sa.ranges_m) == 360 and np.max(np.abs(sa.ranges_m - r1[::2])) <= Q
    assert len(sb.ranges_m) == 720 and sb.angle_increment_rad == pytest.approx(math.radians(0.5))
    inside = slice(90, 90 + 541)  # beams -135 .. +135 deg of the 720-beam grid from -180
    assert np.max(np.abs(sb.ranges_m[inside] - r2)) <= Q
    assert np.all(np.isnan(sb.ranges_m[:90])) and np.all(np.isnan(sb.ranges_m[90 + 541:]))


def test_garbage_in_the_stream_is_counted_and_recovered(emulator):
    emu, path = emulator()
    ranges = np.full(360, 4.0)
    pub = Publisher([emu], [ranges])
    src = open_laser(f"rplidar:{path}")
    try:
        src.start()
        _scans(src, 1)
        emu.inject(bytes.fromhex("00 13 37"))
        scans = _scans(src, 4)
    finally:
        src.close()
        pub.stop()
    assert src.stats.malformed >= 1 and "garbage" in src.stats.last_error
    s, _ = scans[-1]
    assert np.max(np.abs(s.ranges_m - 4.0)) <= Q and src.stats.reconnects == 0


def test_health_error_and_warning(emulator):
    emu, path = emulator()
    emu.health = Health(2, 0x8001)
    src = open_laser(f"rplidar:{path}")
    with pytest.raises(LaserError, match=r"0x8001.*RESET it or power-cycle"):
        src.start()
    emu.health = Health(1, 0x0042)
    pub = Publisher([emu], [np.full(360, 2.0)])
    try:
        src.start()
        assert "warning" in src.stats.last_error and "0x0042" in src.stats.last_error
        _scans(src, 1)
    finally:
        src.close()
        pub.stop()


def test_reconnect_after_the_device_drops(emulator, tmp_path):
    emu1, path1 = emulator()
    emu2, path2 = emulator()
    link = tmp_path / "ttyRPLIDAR"
    os.symlink(path1, link)
    pub = Publisher([emu1, emu2], [np.full(360, 2.0), np.full(360, 3.0)])
    src = open_laser(f"rplidar:{link}")
    src.reconnect_delay_s = 0.05
    try:
        src.start()
        s, _ = _scans(src, 1)[0]
        assert np.nanmax(np.abs(s.ranges_m - 2.0)) <= Q
        tmp = tmp_path / "ttyRPLIDAR.new"
        os.symlink(path2, tmp)
        os.replace(tmp, link)  # the device comes back at the same name
        emu1.close()  # the read of the open port fails as on an unplug
        end = time.monotonic() + 5.0
        s = None
        while time.monotonic() < end:
            s = src.wait(0.5)
            if s is not None and np.nanmax(np.abs(s.ranges_m - 3.0)) <= Q:
                break
        assert s is not None and np.nanmax(np.abs(s.ranges_m - 3.0)) <= Q
        assert src.stats.reconnects == 1
        assert "SerialException" in src.stats.last_error or "readiness" in src.stats.last_error
    finally:
        src.close()
        pub.stop()


def test_a_silent_stream_is_a_lost_device(emulator):
    emu, path = emulator()
    ranges = [np.full(360, 2.0)]
    src = open_laser(f"rplidar:{path}?stall_s=0.3")
    src.spinup_s = 0.0
    src.reconnect_delay_s = 0.05
    try:
        src.start()  # nothing published: SCAN answered, then no samples
        end = time.monotonic() + 3.0
        while src.stats.reconnects == 0 and time.monotonic() < end:
            time.sleep(0.05)
        assert src.stats.reconnects >= 1 and "no samples for 0.3 s" in src.stats.last_error
        pub = Publisher([emu], ranges)
        try:
            _scans(src, 1)
        finally:
            pub.stop()
    finally:
        src.close()


def test_a_port_in_use_is_busy(emulator):
    emu, path = emulator()
    a, b = open_laser(f"rplidar:{path}"), open_laser(f"rplidar:{path}")
    try:
        a.start()
        with pytest.raises(LaserAddressError, match="busy"):
            b.start()
    finally:
        a.close()
        b.close()


def test_wrong_address():
    src = open_laser("rplidar:/dev/ttyRPLIDAR-none")
    with pytest.raises(LaserAddressError, match=r"/dev/ttyRPLIDAR-none: no such serial port"):
        src.start()


def _text_device(reply: bytes):
    def handler(stream, stop):
        while not stop.is_set():
            if stream.read(4096, 0.05) and reply:
                stream.write(reply)
    t = Transport(handler)
    return t, t.open_pty()


@pytest.mark.parametrize("reply, hint", [
    (b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n", "NMEA"),
    (b"VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\n\n", "SCIP"),
])
def test_wrong_device_says_what_answered(reply, hint):
    t, path = _text_device(reply)
    try:
        src = open_laser(f"rplidar:{path}")
        with pytest.raises(WrongDeviceError, match=hint) as e:
            src.start(timeout_s=1.0)
        assert path in str(e.value) and "not an RPLIDAR" in str(e.value)
    finally:
        t.close()


def test_silent_port_is_no_answer():
    t, path = _text_device(b"")
    try:
        with pytest.raises(LaserAddressError, match="no answer to GET_HEALTH"):
            open_laser(f"rplidar:{path}").start(timeout_s=0.3)
    finally:
        t.close()


# ---- a third-party reader on the emulator ---------------------------------------------------------------------
def test_pyrplidar_reads_the_emulator(emulator):
    pyrplidar = pytest.importorskip("pyrplidar")
    emu, path = emulator()
    ranges = np.linspace(0.5, 5.0, 360)
    ranges[10] = np.nan
    pub = Publisher([emu], [ranges])
    lidar = pyrplidar.PyRPlidar()
    try:
        lidar.connect(port=path, baudrate=115200, timeout=2)
        info = lidar.get_info()
        assert (info.model, info.firmware_major, info.firmware_minor, info.hardware) == (0x18, 1, 29, 7)
        assert info.serialnumber == emu.info.serial_hex
        rev, starts = [], 0
        for m in lidar.start_scan()():
            starts += m.start_flag
            if starts == 2:
                rev.append((m.angle, m.distance, m.quality))
            elif starts > 2:
                break
        lidar.stop()
    finally:
        lidar.disconnect()
        pub.stop()
    assert len(rev) == 360
    ours = SampleStream().feed(emu.revolution_bytes(ranges)).samples()
    assert rev == [(s.angle_deg, s.distance_mm, s.quality) for s in ours]
    for angle, dist, _ in rev:
        i = int(round(-angle + 180.0)) % 360  # heading clockwise -> beam counter-clockwise from -180
        if np.isnan(ranges[i]):
            assert dist == 0
        else:
            assert abs(dist / 1000 - ranges[i]) <= Q
