/* CRC-16/CCITT-FALSE, bitwise. See crc16.h. */
#include "crc16.h"

uint16_t crc16_ccitt_false_update(uint16_t crc, const void *data, uint16_t len)
{
    const uint8_t *p = (const uint8_t *)data;
    while (len-- > 0u) {
        crc ^= (uint16_t)((uint16_t)*p++ << 8);
        for (uint8_t bit = 0; bit < 8u; bit++) {
            if ((crc & 0x8000u) != 0u) {
                crc = (uint16_t)((crc << 1) ^ 0x1021u);
            } else {
                crc = (uint16_t)(crc << 1);
            }
        }
    }
    return crc;
}

uint16_t crc16_ccitt_false(const void *data, uint16_t len)
{
    return crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, data, len);
}
