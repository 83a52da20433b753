// libFuzzer target: arbitrary input drives a Device on the FakeBoard. The input is a
// little program: raw serial bytes, well-formed frames (so CRCs don't stop the fuzzer
// at the door) with fuzzed ids, seqs and payloads, fake-time advances, sensor failures
// and TX-ring squeezes. After every operation it checks the invariants below and
// aborts on a violation; sanitizers catch memory errors and UB. Built and run by
// scripts/fuzz-firmware.sh.
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "config.h"
#include "device.h"
#include "fake_board.h"
#include "frame.h"
#include "protocol_catalogue.h"

namespace {

const uint8_t IDS[] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x10, 0x11, 0x12, 0x13, 0x14, 0x80, 0x82, 0x00, 0x7F, 0xFF, 0x15};
const uint32_t MAX_POLLS = 60000;

struct Run {
    fw::FakeBoard board;
    fw::Device dev;
    fw::FrameParser out;  // every byte the device sends must parse
    uint32_t polls;
    uint64_t last_host;
    Run() : dev(board), polls(0), last_host(0) {}
};

const Run* g_run;

void fail(const char* what) {
    fprintf(stderr, "invariant violated: %s\n", what);
    if (g_run) {
        const fw::FakeBoard& b = g_run->board;
        const fw::Device& d = g_run->dev;
        fprintf(stderr, "t=%llu us pos=%d heater=%u sense=%d fault=%u executing=%d queue_free=%u rx_pending=%u "
                        "tx_ring=%u drain=%u step_ring=%u polls=%u\n",
                static_cast<unsigned long long>(b.now), b.position, b.heater_mV, b.sense_on, d.fault(), d.executing(),
                d.queue_free(), b.rx_pending(), b.tx_ring_size, b.tx_drain_bytes_per_ms, b.step_ring_size,
                g_run->polls);
    }
    abort();
}

void check(Run& r) {
    fw::FakeBoard& b = r.board;
    if (b.position < cfg::MIN_TWIST_STEPS || b.position > cfg::MAX_TWIST_STEPS) fail("position out of limits");
    if (b.min_position < cfg::MIN_TWIST_STEPS || b.max_position > cfg::MAX_TWIST_STEPS) fail("passed a limit");
    if (b.heater_mV > 0 && b.sense_on) fail("heater and sense current on together");
    if (b.interlock_violations) fail("heater switched on under sense current");
    if (b.unsettled_conversions) fail("conversion without settled sense current");
    if (b.heater_mV > cfg::MAX_HEATER_MV) fail("heater above limit");
    if (r.dev.urgent_lost()) fail("urgent frame lost");
    if (r.dev.queue_free() > cfg::QUEUE_SLOTS) fail("queue accounting");
    if (!r.dev.position_known() && r.dev.executing() && b.step_busy()) fail("a move while the position is unknown");
    if (r.dev.motor_released() && (b.motor_enabled || b.step_busy())) fail("released motor driven");
    uint8_t buf[256];
    uint32_t n;
    while ((n = b.take_tx(buf, sizeof buf)) > 0) {
        for (uint32_t i = 0; i < n; ++i) r.out.feed(buf[i], b.now);
    }
    if (r.out.errors().total()) fail("device sent a malformed frame");
}

void poll(Run& r, uint32_t times) {
    for (uint32_t i = 0; i < times && r.polls < MAX_POLLS; ++i, ++r.polls) {
        r.dev.poll();
        check(r);
    }
}

void advance(Run& r, uint64_t us) {
    while (us > 0 && r.polls < MAX_POLLS) {
        uint64_t dt = us < 1000 ? us : 1000;
        r.board.advance_us(dt);
        us -= dt;
        poll(r, 1);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    Run r;
    g_run = &r;
    r.board.kept_valid = size > 0 && (data[0] & 0x80);  // a reset that kept the position, or a power-on
    r.dev.boot();
    size_t i = 0;
    while (i < size && r.polls < MAX_POLLS) {
        uint8_t op = data[i++];
        switch (op % 6) {
        case 0: {  // raw bytes
            uint8_t n = i < size ? data[i++] % 64 : 0;
            if (n > size - i) n = static_cast<uint8_t>(size - i);
            r.board.host_write(data + i, n);
            i += n;
            break;
        }
        case 1:
        case 2: {  // a well-formed frame
            if (size - i < 4) {
                i = size;
                break;
            }
            uint8_t id = IDS[data[i] % sizeof IDS];
            uint16_t seq = static_cast<uint16_t>(data[i + 1] % 8);  // small: duplicates happen
            uint8_t len_sel = data[i + 2];
            i += 3;
            int16_t want = proto::payload_size(id);
            uint8_t len = (len_sel & 0x80 || want < 0) ? len_sel % 65 : static_cast<uint8_t>(want);
            uint8_t payload[64] = {0};
            uint8_t avail = static_cast<uint8_t>(size - i < len ? size - i : len);
            memcpy(payload, data + i, avail);
            i += avail;
            uint8_t frame[fw::MAX_WIRE_FRAME];
            uint8_t n = fw::frame_encode(id, seq, payload, len, frame);
            r.board.host_write(frame, n);
            break;
        }
        case 3: {  // time passes
            uint8_t t = i < size ? data[i++] : 0;
            advance(r, static_cast<uint64_t>(t) * t * 40);
            break;
        }
        case 4: {  // sensors misbehave
            uint8_t f = i < size ? data[i++] : 0;
            r.board.position_start_fails = f & 1;
            r.board.position_poll_fails = f & 2;
            r.board.resistance_start_fails = f & 4;
            r.board.resistance_poll_fails = f & 8;
            r.board.position_latency_us = (f & 0x30) * 100U;
            r.board.resistance_latency_us = (f & 0xC0) * 1000U;
            r.board.resistance_flags = static_cast<uint8_t>(f >> 6);
            break;
        }
        default: {  // serial TX ring squeezed, step ring resized
            uint8_t f = i < size ? data[i++] : 0;
            r.board.tx_ring_size = static_cast<uint16_t>(16 + (f & 0x0F) * 32);
            r.board.tx_drain_bytes_per_ms = (f & 0x30) ? 25 : 0;
            r.board.step_ring_size = static_cast<uint8_t>(1 + (f >> 6) * 16);
            break;
        }
        }
        poll(r, 3);
    }
    // Host bytes held back by TX backpressure are still host frames when they are
    // handled; once all are in, the watchdog must stop an active device in time (a
    // controlled stop from the top rate takes 50 ms). Sampling may go on under the
    // latched fault until the release time.
    while (r.board.rx_pending() > 0 && r.polls < MAX_POLLS) advance(r, 1000);
    advance(r, cfg::WATCHDOG_MS * 1000UL + 100000);
    if (r.polls < MAX_POLLS && (r.dev.stopping() || r.board.step_busy())) {
        // A slow move's pending edge and the kept steps run at their own rate (up to a
        // second each at 1 step/s); nothing beyond them may still be queued, and they end.
        if (r.board.steps_pending() > 1u + cfg::STOP_KEEP_MAX_STEPS)
            fail("more than the pending edge and the kept steps still queued after the watchdog period");
        advance(r, (1u + cfg::STOP_KEEP_MAX_STEPS) * 1000000ULL + 100000);
    }
    if (r.polls < MAX_POLLS) {
        if (r.dev.executing() || r.dev.stopping() || r.board.heater_mV > 0 || r.board.step_busy() ||
            r.dev.queue_free() != cfg::QUEUE_SLOTS)
            fail("motor, heater or queue still running after the watchdog period");
        if (r.dev.active() && !r.dev.fault()) fail("active without a latched fault after the watchdog period");
    }
    g_run = 0;
    return 0;
}
