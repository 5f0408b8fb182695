/* Wheel travel into odometry and the encoder health check, see wheels.h. */
#include "wheels.h"

#include "drive.h"
#include "encoder.h"
#include "hal.h"
#include "health.h"
#include "odometry.h"

static uint8_t s_implausible; /* bit i: wheel i's travel was clamped this tick */

void wheels_update_odometry(int16_t steer_cdeg, uint16_t *count_lo, uint16_t *edges_lo)
{
    encoder_update(hal_time_us());
    encoder_motion_t m[ENCODER_MAX];
    s_implausible = 0u;
    for (uint8_t i = 0; i < encoder_params.count; i++) {
        encoder_motion(i, &m[i]);
        count_lo[i] = (uint16_t)m[i].count;
        edges_lo[i] = (uint16_t)m[i].edges;
        if (m[i].delta_um > WHEELS_MAX_TICK_UM || m[i].delta_um < -WHEELS_MAX_TICK_UM) {
            m[i].delta_um = m[i].delta_um > 0 ? WHEELS_MAX_TICK_UM : -WHEELS_MAX_TICK_UM;
            s_implausible = (uint8_t)(s_implausible | (1u << i));
        }
    }
    if (drive_params.kind == DRIVE_DIFFERENTIAL && encoder_params.count >= 2u) {
        int32_t l_um = m[0].delta_um, r_um = m[1].delta_um;
        int32_t l_v = m[0].speed_mm_s, r_v = m[1].speed_mm_s;
        if (encoder_params.count >= 4u) { /* skid steer: wheels 2 (left) and 3 (right) averaged in */
            /* >> 1, not / 2: avr-gcc -Os calls a ~600-cycle division routine for a signed / 2. */
            l_um = (l_um + m[2].delta_um) >> 1;
            r_um = (r_um + m[3].delta_um) >> 1;
            l_v = (l_v + m[2].speed_mm_s) >> 1;
            r_v = (r_v + m[3].speed_mm_s) >> 1;
        }
        odom_update_diff(l_um, r_um, l_v, r_v);
    } else {
        int32_t rear_um = m[0].delta_um, rear_v = m[0].speed_mm_s;
        if (encoder_params.count >= 2u) { /* two rear wheels: their mean is the axle centre */
            rear_um = (rear_um + m[1].delta_um) >> 1;
            rear_v = (rear_v + m[1].speed_mm_s) >> 1;
        }
        odom_update_ackermann(rear_um, steer_cdeg, rear_v);
    }
}

void wheels_check_health(uint32_t now_ms, bool commanded, const uint16_t *count_lo, const uint16_t *edges_lo)
{
    const drive_output_t *d = drive_output();
    bool driving = commanded && (drive_params.kind == DRIVE_DIFFERENTIAL ? (d->left_duty | d->right_duty) != 0u
                                                                           : d->throttle_us != 1500u);
    health_encoders(now_ms, driving, count_lo, edges_lo, (uint8_t)(encoder_faults() | s_implausible));
}
