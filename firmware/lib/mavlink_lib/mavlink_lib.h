/*
 * MAVLink's C library for the firmware: the generated AgNav bindings (agnav_mavlink.h, from
 * protocol/generate.py) with MAVLink's helpers emitted once. agnav_mavlink.h sets
 * MAVLINK_SEPARATE_HELPERS, so the finalize, parser, signing and SHA-256 helpers are only declared
 * there, and mavlink_lib.c defines them. Modules include this header rather than agnav_mavlink.h so
 * that the build (PlatformIO's library finder) links mavlink_lib.c wherever frames are packed or parsed.
 */
#ifndef AGNAV_MAVLINK_LIB_H
#define AGNAV_MAVLINK_LIB_H

#include <agnav_mavlink.h>

#endif /* AGNAV_MAVLINK_LIB_H */
