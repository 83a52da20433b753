// Exchange harness for the core tests: a Device on a FakeBoard, a host side that
// encodes commands and decodes every device frame with the core's own FrameParser.
// Contract: run_us() polls the device while advancing fake time in small increments;
// replies accumulate in order (msg id, seq, decoded fields) until clear().
#pragma once
#include <stdint.h>
#include <string.h>

#include "device.h"
#include "fake_board.h"
#include "frame.h"
#include "protocol_catalogue.h"

namespace core_test {

struct Reply {
    uint8_t id;
    uint16_t seq;
    int64_t f[proto::MAX_DECODED_FIELDS];
    uint8_t nf;
};

class Harness {
public:
    static const int MAX_REPLIES = 1024;

    fw::FakeBoard board;
    fw::Device dev;
    fw::FrameParser host;
    uint16_t host_seq;
    Reply replies[MAX_REPLIES];
    int n;
    uint32_t step_us;
    bool keepalive;  // run_us() sends HEARTBEAT every 250 ms, as the host does
    uint64_t last_keepalive;

    // The board says the position survived a reset at 0 (tests of the unknown position
    // clear board.kept_valid before boot()).
    Harness() : dev(board), host_seq(100), n(0), step_us(50), keepalive(false), last_keepalive(0) {
        board.kept_valid = true;
    }

    void boot() {
        dev.boot();
        poll_once();
    }
    void poll_once() {
        dev.poll();
        collect();
    }
    void run_us(uint64_t us) {
        uint64_t end = board.now + us;
        while (board.now < end) {
            uint64_t dt = end - board.now < step_us ? end - board.now : step_us;
            board.advance_us(dt);
            poll_once();
            if (keepalive && board.now - last_keepalive >= 250000) {
                last_keepalive = board.now;
                heartbeat();
            }
        }
    }
    void collect() {
        uint8_t buf[512];
        uint32_t got;
        while ((got = board.take_tx(buf, sizeof buf)) > 0) {
            for (uint32_t i = 0; i < got; ++i) {
                if (!host.feed(buf[i], board.now) || n >= MAX_REPLIES) continue;
                Reply& r = replies[n++];
                r.id = host.msg_id();
                r.seq = host.seq();
                r.nf = proto::decode_fields(r.id, host.payload(), r.f);
            }
        }
    }
    void clear() { n = 0; }

    // Sends a frame with an explicit seq; polls once so the device handles it.
    void send_seq(uint16_t seq, uint8_t id, const uint8_t* payload, uint8_t len) {
        uint8_t frame[fw::MAX_WIRE_FRAME];
        uint8_t k = fw::frame_encode(id, seq, payload, len, frame);
        board.host_write(frame, k);
        poll_once();
    }
    uint16_t send(uint8_t id, const uint8_t* payload, uint8_t len) {
        uint16_t seq = host_seq++;
        send_seq(seq, id, payload, len);
        return seq;
    }
    template <typename M> uint16_t send_msg(const M& m) {
        uint8_t p[64];
        return send(M::ID, p, proto::pack(m, p));
    }
    uint16_t hello(uint8_t version = proto::PROTOCOL_VERSION, uint32_t hash = proto::CATALOGUE_HASH) {
        proto::Hello h;
        h.protocol_version = version;
        h.catalogue_hash = hash;
        return send_msg(h);
    }
    uint16_t heartbeat() { return send(proto::Heartbeat::ID, 0, 0); }
    uint16_t stop() { return send(proto::Stop::ID, 0, 0); }
    uint16_t clear_queue() { return send(proto::ClearQueue::ID, 0, 0); }
    uint16_t move_to(uint16_t seg, int32_t target, uint32_t rate = 3200, uint32_t accel = 32000) {
        proto::MoveTo m;
        m.segment = seg;
        m.target_steps = target;
        m.rate_steps_per_s = rate;
        m.accel_steps_per_s2 = accel;
        return send_msg(m);
    }
    uint16_t move_by(uint16_t seg, int32_t delta, uint32_t rate = 3200, uint32_t accel = 32000) {
        proto::MoveBy m;
        m.segment = seg;
        m.delta_steps = delta;
        m.rate_steps_per_s = rate;
        m.accel_steps_per_s2 = accel;
        return send_msg(m);
    }
    uint16_t dwell(uint16_t seg, uint32_t us) {
        proto::Dwell m;
        m.segment = seg;
        m.duration_us = us;
        return send_msg(m);
    }
    uint16_t heater(uint16_t seg, uint16_t mV) {
        proto::SetHeater m;
        m.segment = seg;
        m.voltage_mV = mV;
        return send_msg(m);
    }
    uint16_t set_position(int32_t steps) {
        proto::SetPosition m;
        m.position_steps = steps;
        return send_msg(m);
    }
    uint16_t sampling(uint16_t seg, uint32_t period_us) {
        proto::SetSampling m;
        m.segment = seg;
        m.period_us = period_us;
        return send_msg(m);
    }

    // Index of the first reply with this id (and, for EVENT, this kind) from `from`, or -1.
    int find(uint8_t id, int kind = -1, int from = 0) const {
        for (int i = from; i < n; ++i) {
            if (replies[i].id != id) continue;
            if (kind >= 0 && replies[i].f[1] != kind) continue;
            return i;
        }
        return -1;
    }
    int count(uint8_t id, int kind = -1) const {
        int c = 0;
        for (int i = 0; i < n; ++i) {
            if (replies[i].id == id && (kind < 0 || replies[i].f[1] == kind)) ++c;
        }
        return c;
    }
    // Status of the ACK for (seq, id), or -1 when there is none.
    int ack_status(uint16_t seq, uint8_t id) const {
        for (int i = 0; i < n; ++i) {
            const Reply& r = replies[i];
            if (r.id == proto::Ack::ID && r.f[0] == seq && r.f[1] == id) return static_cast<int>(r.f[2]);
        }
        return -1;
    }
    // The last ACK's status and queue_free.
    int last_ack_status() const {
        for (int i = n - 1; i >= 0; --i)
            if (replies[i].id == proto::Ack::ID) return static_cast<int>(replies[i].f[2]);
        return -1;
    }
    int last_ack_free() const {
        for (int i = n - 1; i >= 0; --i)
            if (replies[i].id == proto::Ack::ID) return static_cast<int>(replies[i].f[3]);
        return -1;
    }
    // Runs until an EVENT of this kind arrives or max_us passes; its index or -1.
    int run_until_event(uint8_t kind, uint64_t max_us) {
        uint64_t end = board.now + max_us;
        while (board.now < end) {
            int i = find(proto::Event::ID, kind);
            if (i >= 0) return i;
            run_us(step_us);
        }
        return find(proto::Event::ID, kind);
    }
};

}  // namespace core_test
