/* The committed byte vectors (protocol/vectors/agnav_vectors.json) encoded and decoded by the
 * generated C binding. host/tests/test_protocol_vectors.py checks the same vectors in Python. */
#include <string.h>
#include <unity.h>

#include "mavlink_lib.h"  /* links MAVLink's helpers (lib/mavlink_lib) */
#include <agnav_vectors_test.h>

void setUp(void) {}
void tearDown(void) {}

static void test_vectors_cover_every_agnav_message(void)
{
    /* 8 AgNav messages, one of them with two vectors (physical and raw PWM modes). */
    TEST_ASSERT_GREATER_OR_EQUAL_INT(9, AGNAV_VECTOR_COUNT);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_vectors_cover_every_agnav_message);
    AGNAV_RUN_VECTOR_TESTS();
    return UNITY_END();
}
