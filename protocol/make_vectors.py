#!/usr/bin/env python3
"""Write protocol/vectors/agnav_vectors.json: field values and the exact MAVLink 2 frame of
every AgNav message, encoded by pymavlink from protocol/agnav.xml.

Run it only when a message is added (new vectors); never to make a failing vector test pass:
the point of the committed vectors is that both the C and the Python side must reproduce
them byte for byte.
"""
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "host"))

from agnav_host.protocol import dialect  # noqa: E402

SYSID, COMPID = 1, 1

# Values chosen to hit signs, extremes, arrays and MAVLink 2 zero-trimming.
VECTORS = [
    ("AGNAV_DRIVE_SETPOINT", 0, dict(target_system=1, target_component=1, steer_cdeg=1250,
                                     speed_mm_s=800, steer_pwm=0, speed_pwm=0, mode=0, seq=7)),
    ("AGNAV_DRIVE_SETPOINT", 1, dict(target_system=1, target_component=1, steer_cdeg=-2460,
                                     speed_mm_s=-435, steer_pwm=1380, speed_pwm=1620, mode=1, seq=65535)),
    ("AGNAV_SONAR_RING", 2, dict(time_boot_ms=123456789,
                                 ranges_mm=[300, 4000, 0, 1200, 65535, 25, 2999, 0, 0, 0, 0, 17],
                                 status=[0, 1, 2, 0, 0, 0, 0, 3, 3, 3, 3, 0], count=12, seq=4242)),
    ("AGNAV_BEHAVIOUR_STATUS", 3, dict(time_boot_ms=4294967295, active_layer=2, reason=6,
                                       failsafe_flags=2 | 32, steer_cdeg=-100, speed_mm_s=-50)),
    ("AGNAV_CALIB_TABLE", 4, dict(target_system=1, target_component=1, table_id=0, n_points=4,
                                  pwm=[103, 126, 140, 171] + [0] * 12,
                                  value=[2460, 500, -500, -2460] + [0] * 12,
                                  neutral_pwm=133, dead_band_low_pwm=131, dead_band_high_pwm=135)),
    ("AGNAV_CALIB_REQUEST", 5, dict(target_system=1, target_component=1, table_id=1, action=1)),
    ("AGNAV_CALIB_ACK", 6, dict(table_id=0, result=1, bad_index=2, failsafe_flags=32)),
    ("AGNAV_ENCODER_STATUS", 7, dict(time_boot_ms=60000, count=[2147483647, -2147483648, 1000, -1],
                                     speed_mm_s=[812, -812, 0, 32767], errors=[0, 3, 65535, 1],
                                     count_wheels=4)),
    ("AGNAV_ODOMETRY", 8, dict(time_boot_ms=1000, x_mm=-1234567, y_mm=7654321, yaw_cdeg=18000,
                               speed_mm_s=-2000, yaw_rate_cdeg_s=-4500)),
]


def main() -> int:
    d = dialect()
    out = []
    for name, seq, fields in VECTORS:
        mav = d.MAVLink(None, srcSystem=SYSID, srcComponent=COMPID)
        mav.seq = seq
        cls = getattr(d, f"MAVLink_{name.lower()}_message")
        frame = cls(**fields).pack(mav)
        out.append(dict(name=name, msgid=cls.id, seq=seq, sysid=SYSID, compid=COMPID,
                        fields=fields, frame_hex=frame.hex()))
    path = HERE / "vectors" / "agnav_vectors.json"
    path.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"{len(out)} vectors -> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
