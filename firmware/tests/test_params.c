/* Named parameters: lookup, parsing, key=value splitting. */
#include <string.h>

#include "check.h"
#include "params.h"

static void test_parse_double(void)
{
    double v = 0.0;
    CHECK(param_parse_double("1.5", &v) && v == 1.5);
    CHECK(param_parse_double("-2e-3", &v) && v == -2e-3);
    CHECK(param_parse_double("212.016", &v) && v == 212.016);
    CHECK(!param_parse_double("", &v));
    CHECK(!param_parse_double("fast", &v));
    CHECK(!param_parse_double("1.5x", &v));
    CHECK(!param_parse_double("inf", &v));
    CHECK(!param_parse_double("nan", &v));
    CHECK(!param_parse_double("0x10", &v));
    CHECK(!param_parse_double(" 1", &v));
    CHECK(!param_parse_double("1e999", &v));
}

static void test_set(void)
{
    double a = 0.0, b = 0.0;
    const param_ref_t table[] = {{"kp1", &a}, {"v_max", &b}};
    CHECK(param_set(table, 2, "kp1", "0.25") == PARAM_OK && a == 0.25);
    CHECK(param_set(table, 2, "KP1", "0.5") == PARAM_OK && a == 0.5);
    CHECK(param_set(table, 2, "V_MAX", "8") == PARAM_OK && b == 8.0);
    CHECK(param_set(table, 2, "kp2", "1") == PARAM_UNKNOWN);
    CHECK(param_set(table, 2, "kp1", "one") == PARAM_BAD_VALUE && a == 0.5);
}

static void test_split(void)
{
    char kv[] = "kp1=0.5";
    char *v = param_split(kv);
    CHECK(v != NULL && strcmp(kv, "kp1") == 0 && strcmp(v, "0.5") == 0);
    char bad[] = "=1";
    CHECK(param_split(bad) == NULL);
    char none[] = "kp1";
    CHECK(param_split(none) == NULL);
    char eq2[] = "law=a=b";
    v = param_split(eq2);
    CHECK(v != NULL && strcmp(v, "a=b") == 0);
}

TEST_MAIN("params", test_parse_double, test_set, test_split)
