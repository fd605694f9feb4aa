/* socketcand protocol: message splitting, frame parsing, send formatting. */
#include <string.h>

#include "check.h"
#include "socketcand_proto.h"

static size_t load(char *buf, const char *text)
{
    size_t n = strlen(text);
    memcpy(buf, text, n);
    return n;
}

static void test_split_messages(void)
{
    char buf[1024];
    char body[SCD_MAX_MESSAGE];
    size_t len = load(buf, "< hi >< ok >  < frame 123 1.000000 DEAD >< fra");
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 1);
    CHECK(strcmp(body, "hi") == 0);
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 1);
    CHECK(strcmp(body, "ok") == 0);
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 1);
    CHECK(strcmp(body, "frame 123 1.000000 DEAD") == 0);
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 0); /* partial kept */
    CHECK_INT((long long)len, 5);
    len += load(buf + len, "me 080 2.5  >");
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 1);
    CHECK(strcmp(body, "frame 080 2.5") == 0);
    CHECK_INT((long long)len, 0);
    /* noise without '<' is dropped */
    len = load(buf, "garbage");
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), 0);
    CHECK_INT((long long)len, 0);
    /* an overlong message without '>' is dropped with an error */
    memset(buf, 'x', 700);
    buf[0] = '<';
    len = 700;
    CHECK_INT(scd_next_message(buf, &len, body, sizeof body), -1);
    CHECK_INT((long long)len, 0);
    /* a body that does not fit the caller's buffer */
    len = load(buf, "< frame 123 1.0 0011223344556677 >< ok >");
    char small[8];
    CHECK_INT(scd_next_message(buf, &len, small, sizeof small), -1);
    CHECK_INT(scd_next_message(buf, &len, small, sizeof small), 1);
    CHECK(strcmp(small, "ok") == 0);
}

static void test_parse_frames(void)
{
    hal_can_frame_t f;
    CHECK_INT(scd_parse_frame("frame 123 1700000000.123456 DEADBEEF", &f), 1);
    CHECK_INT(f.id, 0x123);
    CHECK(!f.extended);
    CHECK_INT(f.len, 4);
    CHECK_INT(f.data[0], 0xDE);
    CHECK_INT(f.data[3], 0xEF);
    /* SYNC: no data; the Python server leaves an empty field */
    CHECK_INT(scd_parse_frame("frame 080 12.000100 ", &f), 1);
    CHECK_INT(f.id, 0x80);
    CHECK_INT(f.len, 0);
    /* 29-bit: eight digits, or a value above 0x7FF */
    CHECK_INT(scd_parse_frame("frame 0CFE49F0 1.0 0102030405060708", &f), 1);
    CHECK_INT(f.id, 0x0CFE49F0);
    CHECK(f.extended);
    CHECK_INT(f.len, 8);
    CHECK_INT(f.data[7], 8);
    CHECK_INT(scd_parse_frame("frame 00000080 1.0 ", &f), 1);
    CHECK(f.extended && f.id == 0x80);
    CHECK_INT(scd_parse_frame("frame 18FF2026 1.0 ab", &f), 1);
    CHECK(f.extended && f.data[0] == 0xAB);
    /* bytes separated by spaces (some socketcand versions) */
    CHECK_INT(scd_parse_frame("frame 701 1.0 05 7f", &f), 1);
    CHECK_INT(f.len, 2);
    CHECK_INT(f.data[1], 0x7F);
    /* other words are not frames */
    CHECK_INT(scd_parse_frame("ok", &f), 0);
    CHECK_INT(scd_parse_frame("error 123 1.0", &f), 0);
    CHECK_INT(scd_parse_frame("hi", &f), 0);
    /* malformed */
    CHECK_INT(scd_parse_frame("frame", &f), -1);
    CHECK_INT(scd_parse_frame("frame 12G 1.0 00", &f), -1);
    CHECK_INT(scd_parse_frame("frame 123 1.0 ABC", &f), -1);
    CHECK_INT(scd_parse_frame("frame 123 1.0 001122334455667788", &f), -1);
    CHECK_INT(scd_parse_frame("frame 123456789 1.0 00", &f), -1);
    CHECK_INT(scd_parse_frame("frame 3FFFFFFF 1.0 00", &f), -1);
    CHECK_INT(scd_parse_frame("frame 123 x 00", &f), -1);
}

static void test_format_send(void)
{
    char out[64];
    hal_can_frame_t f = {0x220, false, 4, {0xE8, 0x03, 0x00, 0x00}};
    int n = scd_format_send(&f, out, sizeof out);
    CHECK(n > 0 && strcmp(out, "< send 220 4 E8 03 00 00 >") == 0);
    hal_can_frame_t e = {0x18FF3080, true, 2, {1, 2}};
    n = scd_format_send(&e, out, sizeof out);
    CHECK(n > 0 && strcmp(out, "< send 18FF3080 2 01 02 >") == 0);
    hal_can_frame_t s = {0x80, false, 0, {0}};
    n = scd_format_send(&s, out, sizeof out);
    CHECK(n > 0 && strcmp(out, "< send 080 0 >") == 0);
    hal_can_frame_t x = {0x80, true, 0, {0}};
    n = scd_format_send(&x, out, sizeof out);
    CHECK(n > 0 && strcmp(out, "< send 00000080 0 >") == 0);
    hal_can_frame_t bad_id = {0x800, false, 0, {0}};
    CHECK_INT(scd_format_send(&bad_id, out, sizeof out), -1);
    hal_can_frame_t bad_len = {0x100, false, 9, {0}};
    CHECK_INT(scd_format_send(&bad_len, out, sizeof out), -1);
    char tiny[10];
    CHECK_INT(scd_format_send(&f, tiny, sizeof tiny), -1);
    /* round trip through the parser */
    hal_can_frame_t back;
    char line[64];
    n = scd_format_send(&e, line, sizeof line);
    CHECK(n > 0);
    CHECK_INT(scd_parse_frame("frame 18FF3080 0.0 0102", &back), 1);
    CHECK(back.id == e.id && back.extended && back.len == 2 && back.data[1] == 2);
}

TEST_MAIN("socketcand_proto", test_split_messages, test_parse_frames, test_format_send)
