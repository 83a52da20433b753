// Framing: CRC, COBS, the frame parser and encoder against the golden vectors, and the
// parser under garbage, truncation, over-long runs and inter-byte timeouts.
#include <string.h>

#include "cobs.h"
#include "config.h"
#include "crc16.h"
#include "frame.h"
#include "protocol_catalogue.h"
#include "test_runner.h"

struct GoldenMessage { const char* name; uint16_t seq; const uint8_t* frame; uint8_t frame_len; const int64_t* fields; uint8_t n_fields; };
struct GoldenFrame { const char* name; uint8_t msg_id; uint16_t seq; const uint8_t* payload; uint8_t payload_len; const uint8_t* frame; uint8_t frame_len; };
struct GoldenInvalid { const char* name; const char* reason; const uint8_t* stuffed; uint8_t len; };
#include "golden_vectors.inc"

namespace {

using fw::FrameParser;

uint32_t rng_state;
uint32_t rnd() {
    rng_state = rng_state * 1664525UL + 1013904223UL;
    return rng_state >> 8;
}

// Feeds bytes 10 us apart from t; returns how many frames completed.
int feed_all(FrameParser& p, const uint8_t* data, int n, uint64_t& t) {
    int frames = 0;
    for (int i = 0; i < n; ++i) {
        t += 10;
        if (p.feed(data[i], t)) ++frames;
    }
    return frames;
}

uint16_t reason_count(const fw::FrameErrors& e, const char* reason) {
    if (!strcmp(reason, "crc")) return e.crc;
    if (!strcmp(reason, "cobs")) return e.cobs;
    if (!strcmp(reason, "short")) return e.short_frame;
    if (!strcmp(reason, "version")) return e.version;
    if (!strcmp(reason, "too_long")) return e.too_long;
    return 0xFFFF;
}

}  // namespace

TEST(core_crc16_check_value) {
    const uint8_t s[] = "123456789";
    CHECK_EQ(fw::crc16(s, 9), 0x29B1);
    CHECK_EQ(fw::crc16(s, 0), 0xFFFF);
}

TEST(core_golden_messages_parse_and_reencode) {
    for (unsigned i = 0; i < sizeof GOLDEN_MESSAGES / sizeof GOLDEN_MESSAGES[0]; ++i) {
        const GoldenMessage& g = GOLDEN_MESSAGES[i];
        FrameParser p;
        uint64_t t = 0;
        int frames = 0;
        for (uint8_t k = 0; k < g.frame_len; ++k) {
            bool done = p.feed(g.frame[k], t += 10);
            frames += done;
            if (done) CHECK_EQ(k, g.frame_len - 1);
        }
        CHECK_EQ(frames, 1);
        CHECK_EQ(p.seq(), g.seq);
        CHECK_EQ(p.payload_len(), proto::payload_length(p.msg_id(), p.payload()));
        int64_t fields[proto::MAX_DECODED_FIELDS];
        uint8_t nf = proto::decode_fields(p.msg_id(), p.payload(), fields);
        CHECK_EQ(nf, g.n_fields);
        for (uint8_t f = 0; f < nf && f < g.n_fields; ++f) {
            if (fields[f] != g.fields[f]) testing::note("%s field %u", g.name, f);
            CHECK_EQ(fields[f], g.fields[f]);
        }
        uint8_t out[fw::MAX_WIRE_FRAME];
        uint8_t n = fw::frame_encode(p.msg_id(), p.seq(), p.payload(), p.payload_len(), out);
        CHECK_EQ(n, g.frame_len);
        CHECK(memcmp(out, g.frame, g.frame_len) == 0);
    }
}

TEST(core_golden_frames_encode_and_parse) {
    for (unsigned i = 0; i < sizeof GOLDEN_FRAMES / sizeof GOLDEN_FRAMES[0]; ++i) {
        const GoldenFrame& g = GOLDEN_FRAMES[i];
        uint8_t out[fw::MAX_WIRE_FRAME];
        uint8_t n = fw::frame_encode(g.msg_id, g.seq, g.payload, g.payload_len, out);
        CHECK_EQ(n, g.frame_len);
        CHECK(memcmp(out, g.frame, g.frame_len) == 0);
        FrameParser p;
        uint64_t t = 0;
        CHECK_EQ(feed_all(p, g.frame, g.frame_len, t), 1);
        CHECK_EQ(p.msg_id(), g.msg_id);
        CHECK_EQ(p.seq(), g.seq);
        CHECK_EQ(p.payload_len(), g.payload_len);
        CHECK(memcmp(p.payload(), g.payload, g.payload_len) == 0);
    }
}

TEST(core_golden_invalid_counted_by_reason) {
    for (unsigned i = 0; i < sizeof GOLDEN_INVALID / sizeof GOLDEN_INVALID[0]; ++i) {
        const GoldenInvalid& g = GOLDEN_INVALID[i];
        FrameParser p;
        uint64_t t = 0;
        int frames = feed_all(p, g.stuffed, g.len, t);
        frames += p.feed(0, t += 10);
        CHECK_EQ(frames, 0);
        if (reason_count(p.errors(), g.reason) != 1) testing::note("%s (%s)", g.name, g.reason);
        CHECK_EQ(reason_count(p.errors(), g.reason), 1);
        CHECK_EQ(p.errors().total(), 1);
        // the very next valid frame is never lost
        CHECK_EQ(feed_all(p, GOLDEN_MESSAGES[0].frame, GOLDEN_MESSAGES[0].frame_len, t), 1);
    }
}

TEST(core_cobs_round_trip_random) {
    rng_state = 12345;
    uint8_t in[300], enc[310], dec[300];
    for (int trial = 0; trial < 2000; ++trial) {
        uint16_t n = static_cast<uint16_t>(rnd() % 300);
        int zero_bias = static_cast<int>(rnd() % 4);
        for (uint16_t i = 0; i < n; ++i) in[i] = (rnd() % 4 < static_cast<uint32_t>(zero_bias)) ? 0 : rnd() & 0xFF;
        uint16_t m = fw::cobs_encode(in, n, enc);
        CHECK(m <= n + n / 254 + 1);
        CHECK(memchr(enc, 0, m) == 0);
        int16_t d = fw::cobs_decode(enc, m, dec, sizeof dec);
        CHECK_EQ(d, n);
        CHECK(d < 0 || memcmp(in, dec, n) == 0);
    }
}

TEST(core_cobs_decode_rejects_bad_input) {
    const uint8_t points_past_end[] = {0x05, 0x11, 0x22};
    const uint8_t has_zero[] = {0x03, 0x11, 0x00};
    uint8_t out[8];
    CHECK_EQ(fw::cobs_decode(points_past_end, 3, out, sizeof out), -1);
    CHECK_EQ(fw::cobs_decode(has_zero, 3, out, sizeof out), -1);
    const uint8_t ok[] = {0x03, 0x11, 0x22, 0x01};
    CHECK_EQ(fw::cobs_decode(ok, 4, out, 2), -1);  // output capacity
    CHECK_EQ(fw::cobs_decode(ok, 4, out, 3), 3);
}

TEST(core_parser_resyncs_after_garbage) {
    rng_state = 777;
    const GoldenMessage& g = GOLDEN_MESSAGES[5];
    for (int trial = 0; trial < 500; ++trial) {
        FrameParser p;
        uint64_t t = 0;
        uint8_t garbage[200];
        int n = static_cast<int>(rnd() % 200);
        for (int i = 0; i < n; ++i) garbage[i] = rnd() & 0xFF;
        int frames = feed_all(p, garbage, n, t);
        frames += p.feed(0, t += 10);
        CHECK_EQ(frames, 0);
        CHECK_EQ(feed_all(p, g.frame, g.frame_len, t), 1);
        CHECK_EQ(p.seq(), g.seq);
    }
}

TEST(core_parser_random_garbage_never_yields_a_frame) {
    rng_state = 4242;
    FrameParser p;
    uint64_t t = 0;
    int frames = 0;
    for (int i = 0; i < 300000; ++i) {
        uint32_t r = rnd();
        uint8_t b = (r & 0x700) == 0 ? 0 : static_cast<uint8_t>(r);  // delimiters ~1 in 8
        frames += p.feed(b, t += 10);
    }
    CHECK_EQ(frames, 0);
    CHECK(p.errors().total() > 1000);
}

TEST(core_parser_truncated_frame_then_valid) {
    const GoldenMessage& g = GOLDEN_MESSAGES[11];
    for (uint8_t cut = 1; cut < g.frame_len - 1; ++cut) {
        FrameParser p;
        uint64_t t = 0;
        int frames = feed_all(p, g.frame, cut, t);
        frames += p.feed(0, t += 10);
        CHECK_EQ(frames, 0);
        CHECK_EQ(p.errors().total(), 1);
        CHECK_EQ(feed_all(p, g.frame, g.frame_len, t), 1);
    }
}

TEST(core_parser_too_long_discarded_to_next_delimiter) {
    FrameParser p;
    uint64_t t = 0;
    uint8_t junk[500];
    memset(junk, 0x41, sizeof junk);
    CHECK_EQ(feed_all(p, junk, sizeof junk, t), 0);
    CHECK_EQ(p.errors().too_long, 1);
    CHECK_EQ(p.feed(0, t += 10), false);
    CHECK_EQ(p.errors().total(), 1);
    CHECK_EQ(feed_all(p, GOLDEN_MESSAGES[0].frame, GOLDEN_MESSAGES[0].frame_len, t), 1);
    // the longest frame the catalogue allows is accepted
    const GoldenFrame& longest = GOLDEN_FRAMES[1];
    CHECK(longest.frame_len <= fw::MAX_WIRE_FRAME);
    CHECK_EQ(feed_all(p, longest.frame, longest.frame_len, t), 1);
}

TEST(core_parser_idle_delimiters_are_not_errors) {
    FrameParser p;
    uint64_t t = 0;
    for (int i = 0; i < 100; ++i) CHECK(!p.feed(0, t += 10));
    CHECK_EQ(p.errors().total(), 0);
}

TEST(core_parser_interbyte_timeout_drops_half_frame) {
    const GoldenMessage& g = GOLDEN_MESSAGES[5];
    FrameParser p;
    uint64_t t = 0;
    feed_all(p, g.frame, 7, t);            // a stalled half frame
    t += cfg::FRAME_TIMEOUT_US + 1;
    CHECK_EQ(feed_all(p, g.frame, g.frame_len, t), 1);  // not glued to the stale half
    CHECK_EQ(p.errors().timeout, 1);
    CHECK_EQ(p.errors().total(), 1);
    // a pause just inside the timeout keeps the frame together
    feed_all(p, g.frame, 7, t);
    t += cfg::FRAME_TIMEOUT_US - 20;
    CHECK_EQ(feed_all(p, g.frame + 7, g.frame_len - 7, t), 1);
    CHECK_EQ(p.errors().total(), 1);
}

TEST(core_parser_timeout_ends_overflow_discard) {
    FrameParser p;
    uint64_t t = 0;
    uint8_t junk[100];
    memset(junk, 0x41, sizeof junk);
    feed_all(p, junk, sizeof junk, t);
    t += cfg::FRAME_TIMEOUT_US + 1;
    const GoldenMessage& g = GOLDEN_MESSAGES[1];
    CHECK_EQ(feed_all(p, g.frame, g.frame_len, t), 1);
}

TEST(core_encode_seq_and_payload_round_trip) {
    rng_state = 99;
    FrameParser p;
    uint64_t t = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        uint8_t payload[64];
        uint8_t len = static_cast<uint8_t>(rnd() % 65);
        for (uint8_t i = 0; i < len; ++i) payload[i] = static_cast<uint8_t>(rnd() % 3 == 0 ? 0 : rnd());
        uint16_t seq = static_cast<uint16_t>(rnd());
        uint8_t id = static_cast<uint8_t>(rnd());
        uint8_t out[fw::MAX_WIRE_FRAME];
        uint8_t n = fw::frame_encode(id, seq, payload, len, out);
        CHECK(n <= fw::MAX_WIRE_FRAME);
        CHECK_EQ(feed_all(p, out, n, t), 1);
        CHECK_EQ(p.msg_id(), id);
        CHECK_EQ(p.seq(), seq);
        CHECK_EQ(p.payload_len(), len);
        CHECK(memcmp(p.payload(), payload, len) == 0);
    }
}
