/*
 * The firmware's records for lib/storage: storage_record_slots() and storage_record_byte() (declared
 * in storage.h) for the parameters (lib/params), the calibration tables (lib/calib) and the signing
 * key (lib/signing), at the addresses their owners' headers give (EEPROM map in storage.h). Kept out
 * of lib/storage so that it links none of the records' owners (its tests bring records of their own).
 */
#ifndef AGNAV_STORAGE_RECORDS_H
#define AGNAV_STORAGE_RECORDS_H

#include "storage.h"

#endif /* AGNAV_STORAGE_RECORDS_H */
