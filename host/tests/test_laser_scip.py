"""Hokuyo SCIP 2.0: the codec on the specification's own examples, malformed replies, the emulator's answers, and
the driver against the emulator over loopback TCP (ust) and a pty (urg).

Hand-written replies follow Hokuyo C-42-03320B (*Communication Protocol Specification For SCIP2.0 Standard*):
the encoding examples of section 6 (1234 = ``CB``, 5432 = ``1Dh``, 16,000,000 = ``m2@0``), the statuses ``00P``
and ``99b``, and the VV / PP / II examples of sections 8.11-8.13. Every socket is on 127.0.0.1 with port 0.
"""

from __future__ import annotations

import math
import socket
import threading
import time

import numpy as np
import pytest

from agnav_host.lasers import LaserAddressError, LaserUrlError, TelegramError, WrongDeviceError, open_laser
from agnav_host.lasers.scip import (
    BlockReader,
    NotScipText,
    ScipParams,
    checksum,
    data_lines,
    decode,
    decode_array,
    encode,
    encode_array,
    parse_block,
    parse_info,
    parse_reply,
    parse_scan,
    parse_status,
    parse_time,
    scan_command,
)
from agnav_host.sil.emulators.base import ScanGeometry
from agnav_host.sil.emulators.scip import ScipEmulator, params_from_geometry

# ---- the codec on the specification's examples ---------------------------------------------------------------

VV_EXAMPLE = (b"VV\n00P\n"
              b"VEND:Hokuyo Automatic Co.,Ltd.;[\n"
              b"PROD:SOKUIKI Sensor URG-04LX;[\n"
              b"FIRM:3.1.00(18/Jan./2007);`\n"
              b"PROT:SCIP 2.0;N\n"
              b"SERI:H0614967;V\n\n")

PP_EXAMPLE = (b"PP\n00P\n"
              b"MODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\n"
              b"DMIN:20;4\n"
              b"DMAX:5600;_\n"
              b"ARES:1024;\\\n"
              b"AMIN:44;7\n"
              b"AMAX:725;o\n"
              b"AFRT:384;6\n"
              b"SCAN:600;e\n\n")

II_EXAMPLE = (b"II\n00P\n"
              b"MODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\n"
              b"LASR:OFF;7\n"
              b"SCSP:Initial(600[rpm])<-Default setting by user;A\n"
              b"MESM:IDLE;:\n"
              b"SBPS:19200[bps]<-Default setting by user;A\n"
              b"TIME:081615;N\n"
              b"STAT:Sensor works well.;8\n\n")

# GD over steps 44..65 (22 values, 66 characters: a 64-character block and a 2-character one): twenty 5432 mm
# (``1Dh``), an error code 1 (``001``) and 1234 mm (``0CB``); time stamp 16,000,000 ms (``m2@0``, sum ``?``).
GD_EXAMPLE = (b"GD0044006500\n00P\nm2@0?\n"
              b"1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh00105\n"
              b"CB5\n\n")
GS_EXAMPLE = b"GS0044004600\n00P\nm2@0?\nCBCBCB?\n\n"  # three 1234 mm in 2-character encoding
MD_EXAMPLE = b"MD0044004600001\n99b\nm2@0?\n1Dh0CB001S\n\n"  # one scan left after this one
ME_EXAMPLE = b"ME0044004501000\n99b\nm2@0?\n1Dh0CB0CB1DhT\n\n"  # (5432 mm, 1234), (1234 mm, 5432)


def test_encodings_are_the_specification_examples():
    assert encode(1234, 2) == "CB" and decode("CB") == 1234
    assert encode(5432, 3) == "1Dh" and decode("1Dh") == 5432
    assert encode(16_000_000, 4) == "m2@0" and decode("m2@0") == 16_000_000
    assert list(decode_array("1Dh0CB001", 3)) == [5432, 1234, 1]
    assert encode_array([5432, 1234, 1], 3) == "1Dh0CB001"
    assert checksum("00") == "P" and checksum("99") == "b"
    with pytest.raises(ValueError, match="does not fit 2 characters"):
        encode(4096, 2)
    with pytest.raises(TelegramError, match="not an encoded character"):
        decode("1D~")


def test_vv_pp_ii_examples_parse_with_their_sums():
    vv = parse_reply(parse_block(VV_EXAMPLE), "VV").require()
    info = parse_info(vv.body)
    assert info["PROD"] == "SOKUIKI Sensor URG-04LX" and info["PROT"] == "SCIP 2.0" and info["SERI"] == "H0614967"
    pp = ScipParams.from_info(parse_info(parse_reply(parse_block(PP_EXAMPLE), "PP").require().body))
    assert (pp.dmin_mm, pp.dmax_mm, pp.ares, pp.amin, pp.amax, pp.afrt, pp.scan_rpm) == (20, 5600, 1024, 44, 725,
                                                                                          384, 600)
    assert pp.model == "URG-04LX(Hokuyo Automatic Co.,Ltd.)"
    assert pp.angle_rad(44) == pytest.approx(-340 * 2 * math.pi / 1024)  # anti-clockwise steps, front = AFRT
    assert pp.angle_rad(725) == pytest.approx(341 * 2 * math.pi / 1024)
    assert pp.step_s == pytest.approx(0.1 / 1024) and pp.scan_hz == 10.0
    ii = parse_info(parse_reply(parse_block(II_EXAMPLE), "II").require().body)
    assert ii["LASR"] == "OFF" and ii["TIME"] == "081615" and ii["STAT"] == "Sensor works well."


def test_scan_replies_written_by_hand():
    gd = parse_scan(parse_block(GD_EXAMPLE))
    assert (gd.code, gd.start, gd.end, gd.cluster, gd.timestamp_ms) == ("GD", 44, 65, 0, 16_000_000)
    assert list(gd.ranges_mm) == [5432] * 20 + [1, 1234] and gd.intensities is None
    gs = parse_scan(parse_block(GS_EXAMPLE))
    assert list(gs.ranges_mm) == [1234, 1234, 1234]
    md = parse_scan(parse_block(MD_EXAMPLE))
    assert md.remaining == 1 and list(md.ranges_mm) == [5432, 1234, 1]
    me = parse_scan(parse_block(ME_EXAMPLE))
    assert list(me.ranges_mm) == [5432, 1234] and list(me.intensities) == [1234, 5432]
    assert data_lines("1Dh" * 20 + "0010CB") == ["1Dh" * 20 + "0010" + "5", "CB5"]  # the GD example's lines


def test_commands():
    assert scan_command("MD", 44, 725) == b"MD0044072500000\n"
    assert scan_command("GD", 0, 1080, 1) == b"GD0000108001\n"
    assert scan_command("MS", 0, 10, 2, 1, 5, tag="run_1") == b"MS0000001002105;run_1\n"
    with pytest.raises(ValueError, match="at most 16"):
        scan_command("MD", 0, 10, tag="x" * 17)
    with pytest.raises(ValueError, match="at most 16"):
        scan_command("MD", 0, 10, tag="a;b")


def _replace(data: bytes, old: bytes, new: bytes) -> bytes:
    assert old in data
    return data.replace(old, new, 1)


@pytest.mark.parametrize("data, match", [
    (_replace(GD_EXAMPLE, b"00P", b"00Q"), "status '00' has sum 'Q', expected 'P'"),
    (_replace(GD_EXAMPLE, b"00105\n", b"00106\n"), "data block 1 has sum '6', expected '5'"),
    (_replace(GD_EXAMPLE, b"m2@0?", b"m2@0!"), "time 'm2@0' has sum '!'"),
    (_replace(GD_EXAMPLE, b"CB5\n", b""), "64 data characters for 22 values"),
    (_replace(GD_EXAMPLE, b"1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh00105\n",
              b"1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh1Dh001" + checksum("1Dh" * 20 + "001").encode()
              + b"\n"), "data block 1 has 63 characters"),
    (_replace(GD_EXAMPLE, b"GD0044006500\n00P", b"GD0044006500\n04T"), "status 04 .end step is out of range"),
    (_replace(GD_EXAMPLE, b"GD0044006500\n00P", b"GD0044006500\n10Q"), "status 10 .the laser is off"),
    (_replace(MD_EXAMPLE, b"99b", b"00P"), "a scan has 99"),
    (b"MD0044004600001\n99b\n\n", "no time stamp"),
    (_replace(GD_EXAMPLE, b"GD0044006500", b"GD004400650"), "takes 10 digits"),
    (_replace(GD_EXAMPLE, b"GD0044006500", b"GD0065004400"), "end step before the start step"),
    (_replace(GD_EXAMPLE, b"\n\n", b"\n"), "no LF LF terminator"),
    (_replace(GD_EXAMPLE, b"CB5", b"C\x01B"), "control characters"),
    (_replace(GD_EXAMPLE, b"CB5", b"C\xc3B"), "non-ASCII"),
])
def test_malformed_scan_replies_raise_telegram_errors(data, match):
    with pytest.raises(TelegramError, match=match):
        parse_scan(parse_block(data))


def test_malformed_status_and_information_lines():
    with pytest.raises(TelegramError, match="echo 'VX' does not match the command 'VV'"):
        parse_reply(parse_block(_replace(VV_EXAMPLE, b"VV\n", b"VX\n")), "VV")
    with pytest.raises(TelegramError, match="status 0E .undefined command"):
        parse_reply(parse_block(b"XX\n0Ee\n\n"), "XX").require()
    with pytest.raises(TelegramError, match="has sum '5', expected '4'"):
        parse_info(parse_reply(parse_block(_replace(PP_EXAMPLE, b"DMIN:20;4", b"DMIN:20;5"))).body)
    with pytest.raises(TelegramError, match="does not end in ';' and a sum"):
        parse_info(parse_reply(parse_block(_replace(PP_EXAMPLE, b"DMIN:20;4", b"DMIN:20"))).body)
    with pytest.raises(TelegramError, match="lacks AFRT"):
        ScipParams.from_info(parse_info(parse_reply(parse_block(_replace(PP_EXAMPLE, b"AFRT:384;6\n", b""))).body))
    with pytest.raises(TelegramError, match="not 2 status characters"):
        parse_status("0P")
    assert parse_time("m2@0?") == 16_000_000


def test_block_reader_splits_joins_and_resyncs():
    chunks = [GD_EXAMPLE[:7], GD_EXAMPLE[7:50], GD_EXAMPLE[50:] + VV_EXAMPLE + b"\x02sRA Dev",
              b"iceIdent\x03\n\n", b"QT\n00P\n\n"]

    def recv(timeout_s):
        if chunks:
            return chunks.pop(0)
        time.sleep(min(timeout_s, 0.01))
        return b""

    r = BlockReader(recv)
    lines, n = r.read_block(1.0)
    assert lines[0] == "GD0044006500" and n == len(GD_EXAMPLE)
    lines, _ = r.read_block(1.0)  # VV arrived in the same chunk as the rest of GD
    assert lines[0] == "VV" and len(lines) == 7
    with pytest.raises(NotScipText, match="not SCIP text") as e:
        r.read_block(1.0)
    assert e.value.raw.startswith(b"\x02sRA")
    lines, _ = r.read_block(1.0)  # the rest of the bad telegram is skipped up to its blank line
    assert lines == ["QT", "00P"]
    with pytest.raises(Exception) as t:
        r.read_block(0.05)
    assert type(t.value).__name__ == "_ReadTimeout"


# ---- the emulator --------------------------------------------------------------------------------------------

UST = ScanGeometry(angle_min_rad=-3 * math.pi / 4, angle_increment_rad=2 * math.pi / 1440, n_beams=1081,
                   range_min_m=0.05, range_max_m=30.0, scan_hz=40.0)  # UST-10LX steps, DMIN raised to 50 mm
URG = ScanGeometry(angle_min_rad=-340 * 2 * math.pi / 1024, angle_increment_rad=2 * math.pi / 1024, n_beams=682,
                   range_min_m=0.05, range_max_m=5.6, scan_hz=20.0)


def test_pp_from_geometry():
    p = params_from_geometry(UST)
    assert (p.ares, p.amin, p.amax, p.afrt, p.dmin_mm, p.dmax_mm, p.scan_rpm) == (1440, 0, 1080, 540, 50, 30000, 2400)
    q = params_from_geometry(ScanGeometry(math.radians(10), math.radians(1), 20))
    assert (q.ares, q.afrt, q.amin, q.amax) == (360, 0, 10, 29)
    with pytest.raises(ValueError, match="whole number of steps"):
        params_from_geometry(ScanGeometry(0.0, math.radians(0.7), 100))
    with pytest.raises(ValueError, match="not a whole number of steps"):
        params_from_geometry(ScanGeometry(math.radians(0.5), math.radians(1), 100))
    with pytest.raises(ValueError, match="do not fit one turn"):
        params_from_geometry(ScanGeometry(-math.pi, math.radians(1), 361))


def _pattern(n: int, seq: int = 0) -> np.ndarray:
    """Beam i at 1.000 + i mm... m, except: beam 0 carries seq; 3 NaN, 4 inf, 5 at 5 mm (error code), 6 at 30 mm
    (below DMIN), 7 beyond range_max."""
    r = 1.0 + 0.001 * np.arange(n)
    r[0] = 1.0 + 0.001 * (seq % 1000)
    r[3], r[4], r[5], r[6], r[7] = np.nan, np.inf, 0.005, 0.03, 99.0
    return r


BAD_BEAMS = (3, 4, 5, 6, 7)


class _Feed:
    """Publishes ``_pattern`` scans at the geometry's rate; ``t_s`` = host monotonic - T0 + shift."""

    def __init__(self, em: ScipEmulator, shift_s: float = 0.0) -> None:
        self.em, self.shift_s = em, shift_s
        self.t0 = time.monotonic()
        self.host_t: dict[int, float] = {}  # seq % 1000 -> host time the scan's t_s stands for
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        seq, period = 0, 1.0 / self.em.geometry.scan_hz
        while not self._stop.is_set():
            now = time.monotonic()
            self.host_t[seq % 1000] = now
            self.em.publish(_pattern(self.em.geometry.n_beams, seq), now - self.t0 + self.shift_s)
            seq += 1
            self._stop.wait(period)

    def __enter__(self) -> "_Feed":
        self._thread.start()
        time.sleep(0.05)
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2.0)


@pytest.fixture
def ust_emulator():
    em = ScipEmulator("ust", UST, port=0)
    em.start()
    yield em
    em.close()


def _xchg(sock: socket.socket, cmd: bytes, blocks: int = 1) -> bytes:
    out = b""
    sock.sendall(cmd)
    while out.count(b"\n\n") < blocks:
        chunk = sock.recv(65536)
        assert chunk, "the emulator closed the connection"
        out += chunk
    return out


def test_emulator_answers_byte_for_byte(ust_emulator):
    em = ust_emulator
    with _Feed(em), socket.create_connection(("127.0.0.1", em.port), timeout=2) as s:
        assert _xchg(s, b"XX\n") == b"XX\n0Ee\n\n"
        assert _xchg(s, b"SCIP2.0\n") == b"SCIP2.0\n0\n\n"
        assert _xchg(s, b"QT;ab.c\r\n") == b"QT;ab.c\n00P\n\n"  # CR LF ends a command; the echo keeps the string
        assert _xchg(s, b"QT;" + b"x" * 17 + b"\n").endswith(b"\n0Gg\n\n")
        pp = parse_info(parse_reply(parse_block(_xchg(s, b"PP\n")), "PP").require().body)
        assert pp["ARES"] == "1440" and pp["AFRT"] == "540" and pp["DMAX"] == "30000" and pp["SCAN"] == "2400"
        assert parse_info(parse_reply(parse_block(_xchg(s, b"VV\n")), "VV").require().body)["PROT"] == "SCIP 2.0"
        assert _xchg(s, b"GD0000108000\n") == b"GD0000108000\n10Q\n\n"  # laser off
        assert _xchg(s, b"MD0000\n") == b"MD0000\n0Cc\n\n"
        assert _xchg(s, b"MD00a0108000000\n") == b"MD00a0108000000\n01Q\n\n"
        assert _xchg(s, b"MD0000108100000\n") == b"MD0000108100000\n04T\n\n"  # beyond AMAX
        assert _xchg(s, b"MD0100005000000\n") == b"MD0100005000000\n05U\n\n"
        assert _xchg(s, b"TM1\n") == b"TM1\n04T\n\n"
        assert _xchg(s, b"TM0\n") == b"TM0\n00P\n\n"
        tm1 = parse_reply(parse_block(_xchg(s, b"TM1\n")), "TM1").require()
        assert len(tm1.body) == 1 and parse_time(tm1.body[0]) >= 0
        assert _xchg(s, b"TM2\n") == b"TM2\n00P\n\n"
        assert _xchg(s, b"BM\n") == b"BM\n00P\n\n"
        assert _xchg(s, b"BM\n") == b"BM\n02R\n\n"
        gd = parse_scan(parse_block(_xchg(s, b"GD0000108003\n")))  # clusters of 3: the least valid value
        assert len(gd.ranges_mm) == 361  # ceil(1081 / 3)
        assert list(gd.ranges_mm[1:4]) == [1, 30, 1009]  # steps 3-5 no valid value: the first code; 6-8: 30 mm
        assert gd.ranges_mm[-1] == 2080  # the last cluster holds step 1080 alone
        ms = _xchg(s, b"MS0010001900002\n", blocks=3).split(b"\n\n")  # two scans, then the run ends
        assert ms[0] == b"MS0010001900002\n00P"
        first, second = parse_scan(parse_block(ms[1] + b"\n\n")), parse_scan(parse_block(ms[2] + b"\n\n"))
        assert (first.remaining, second.remaining) == (1, 0)
        assert list(first.ranges_mm) == [1010 + i for i in range(10)]
        assert second.timestamp_ms > first.timestamp_ms
        assert _xchg(s, b"QT\n") == b"QT\n00P\n\n"


@pytest.mark.parametrize("kind, mode", [("ust", "md"), ("ust", "gd"), ("urg", "md"), ("urg", "gd")])
def test_driver_reads_geometry_ranges_and_stamps(kind, mode):
    geom = UST if kind == "ust" else URG
    em = ScipEmulator(kind, geom, port=0)
    where = em.start()
    try:
        with _Feed(em) as feed:
            url = f"ust://127.0.0.1:{em.port}?mode={mode}" if kind == "ust" else f"urg:{where}?mode={mode}"
            laser = open_laser(url)
            try:
                info = laser.start(timeout_s=3.0)
                assert info.kind == kind and info.stamps == "device" and info.scan_hz == geom.scan_hz
                assert "SOKUIKI" in info.model and info.serial.startswith("EMU")
                assert laser.tm_round_trip_s is not None
                scans = []
                while len(scans) < 8:
                    scan = laser.wait(2.0)
                    assert scan is not None, laser.stats
                    scans.append((scan, time.monotonic()))
            finally:
                laser.close()
        assert laser.tm_used
        assert laser.stats.malformed == 0 and laser.stats.reconnects == 0
        stamps = [s.stamp_s for s, _ in scans]
        assert all(b > a for a, b in zip(stamps, stamps[1:]))
        for scan, got in scans:
            assert scan.angle_min_rad == pytest.approx(geom.angle_min_rad, abs=1e-12)
            assert scan.angle_increment_rad == pytest.approx(geom.angle_increment_rad, rel=1e-12)
            assert len(scan.ranges_m) == geom.n_beams and scan.range_max_m == geom.range_max_m
            mm = scan.ranges_m * 1000.0
            assert np.isnan(mm[list(BAD_BEAMS)]).all()
            good = np.setdiff1d(np.arange(1, geom.n_beams), BAD_BEAMS)
            assert np.array_equal(np.round(mm[good]), 1000 + good)
            seq = round(mm[0]) - 1000
            assert scan.stamp_s <= got  # mapped onto the monotonic clock, never after arrival
            assert abs(scan.stamp_s - feed.host_t[seq]) < 0.02  # the published t_s, as host time
    finally:
        em.close()


def test_stamps_cross_the_24_bit_wrap(ust_emulator):
    wrap_s = 2**24 / 1000.0
    with _Feed(ust_emulator, shift_s=wrap_s - 0.15) as feed:  # the device's ms counter wraps 0.1 s in
        laser = open_laser(f"ust://127.0.0.1:{ust_emulator.port}")
        try:
            laser.start(timeout_s=3.0)
            scans = [laser.wait(2.0) for _ in range(16)]
        finally:
            laser.close()
    assert all(s is not None for s in scans)
    stamps = np.array([s.stamp_s for s in scans])
    # the intervals of the times the feed published these scans at (a loaded machine wakes it late now and then)
    published = np.array([feed.host_t[round(s.ranges_m[0] * 1000) - 1000] for s in scans])
    assert (np.diff(stamps) > 0.015).all(), np.diff(stamps)  # no step back, no stall across the wrap
    assert (np.abs(np.diff(stamps) - np.diff(published)) < 0.005).all(), (np.diff(stamps), np.diff(published))
    assert (np.abs(stamps - published) < 0.02).all()


def test_reconnect_after_the_emulator_drops_the_client(ust_emulator):
    with _Feed(ust_emulator):
        laser = open_laser(f"ust://127.0.0.1:{ust_emulator.port}")
        try:
            laser.start(timeout_s=3.0)
            assert laser.wait(2.0) is not None
            ust_emulator.drop_clients()
            end = time.monotonic() + 5.0
            while laser.stats.reconnects < 1 and time.monotonic() < end:
                time.sleep(0.02)
            assert laser.stats.reconnects == 1, laser.stats
            laser.latest()
            after = [laser.wait(2.0) for _ in range(3)]
        finally:
            laser.close()
    assert all(s is not None for s in after)
    assert laser.stats.reconnects == 1
    assert "closed the connection" in laser.stats.last_error


def test_a_corrupt_scan_in_the_stream_is_counted_and_skipped(ust_emulator, monkeypatch):
    real = ust_emulator._scan_reply
    calls = []

    def corrupt_third(*args):
        calls.append(1)
        data = real(*args)
        return data.replace(b"\n99b\n", b"\n99c\n") if len(calls) == 3 else data

    monkeypatch.setattr(ust_emulator, "_scan_reply", corrupt_third)
    with _Feed(ust_emulator):
        laser = open_laser(f"ust://127.0.0.1:{ust_emulator.port}")
        try:
            laser.start(timeout_s=3.0)
            scans = [laser.wait(2.0) for _ in range(5)]
        finally:
            laser.close()
    assert all(s is not None for s in scans)
    assert laser.stats.malformed == 1 and laser.stats.reconnects == 0
    assert "status '99' has sum 'c', expected 'b'" in laser.stats.last_error


def test_wrong_addresses():
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    with pytest.raises(LaserAddressError, match=f"connection refused at 127.0.0.1:{port}"):
        open_laser(f"ust://127.0.0.1:{port}").start(timeout_s=1.0)
    with pytest.raises(LaserAddressError, match="no such serial device '/dev/ttyACM_agnav_missing'.*ls /dev/ttyACM"):
        open_laser("urg:/dev/ttyACM_agnav_missing").start(timeout_s=1.0)
    with pytest.raises(LaserUrlError, match="mode must be md"):
        open_laser("ust://127.0.0.1?mode=fast")
    with pytest.raises(LaserUrlError, match="unknown option 'rate'"):
        open_laser("urg:/dev/ttyACM0?rate=3")


def _answering_server(answer: bytes):
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(5.0)

    def serve():
        try:
            conn, _ = srv.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(3.0)
            try:
                while conn.recv(4096):
                    conn.sendall(answer)
            except OSError:
                pass

    threading.Thread(target=serve, daemon=True).start()
    return srv


def test_wrong_devices():
    srv = _answering_server(b"\x02sRA DeviceIdent 8 TiM561 10 V3.15-05.17\x03")
    try:
        with pytest.raises(WrongDeviceError, match="like a SICK CoLa scanner.*not a Hokuyo"):
            open_laser(f"ust://127.0.0.1:{srv.getsockname()[1]}").start(timeout_s=2.0)
    finally:
        srv.close()
    srv = _answering_server(b"HELLO 1.0 ready\r\n\r\n")
    try:
        with pytest.raises(WrongDeviceError, match="nothing answered the SCIP VV command.*'HELLO 1.0 ready'"):
            open_laser(f"ust://127.0.0.1:{srv.getsockname()[1]}").start(timeout_s=1.7)
    finally:
        srv.close()


def test_hokuyolx_reads_the_ust_emulator(ust_emulator):
    hokuyolx = pytest.importorskip("hokuyolx")
    with _Feed(ust_emulator):
        # tsync=False: hokuyolx's time sync asks %ST (a UST-only command the SCIP 2.0 emulator answers with 0E);
        # convert_time=False keeps its time stamps raw (it would compare them with the wall clock).
        lx = hokuyolx.HokuyoLX(addr=("127.0.0.1", ust_emulator.port), tsync=False, convert_time=False, timeout=2)
        try:
            assert (lx.amin, lx.amax, lx.aforw, lx.ares, lx.dmin, lx.dmax) == (0, 1080, 540, 1440, 50, 30000)
            ts, mm = lx.get_dist()
        finally:
            lx.close()
        laser = open_laser(f"ust://127.0.0.1:{ust_emulator.port}?mode=gd")
        try:
            laser.start(timeout_s=3.0)
            ours = laser.wait(2.0)
        finally:
            laser.close()
    assert 0 <= ts < 2**24 and len(mm) == 1081
    expected = np.round(_pattern(1081) * 1000.0)
    expected[[3, 4, 7]], expected[5] = 1, 4  # no object / too near, as the emulator codes them
    assert np.array_equal(mm[1:], expected[1:])
    finite = np.isfinite(ours.ranges_m)
    assert np.array_equal(np.round(ours.ranges_m[finite][1:] * 1000), mm[finite][1:])
