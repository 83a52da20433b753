#include "planner.h"

#include "board.h"
#include "flash.h"
#include "isqrt.h"

namespace fw {

namespace {

#include "ramp_tables.inc"

const uint32_t F_Q8 = STEP_TICK_HZ << 8;  // 2e6 * 256 < 2^32
// 256 f sqrt(2), times 2 (see c0_q8).
const uint32_t C0_NUM_X2 = 1448154688UL;
const uint16_t INV_SQRT2_Q16 = 46341;
const uint32_t TABLE_K = 256;
const uint32_t NONE = 0xFFFFFFFFUL;

// (a * b) >> 16 for b < 65536, without 64-bit multiplies.
uint32_t mul_q16(uint32_t a, uint16_t b) {
    return (a >> 16) * b + (((a & 0xFFFFUL) * b) >> 16);
}

}  // namespace

uint32_t StepPlanner::c0_q8(uint32_t accel) {
    if (accel == 0) accel = 1;
    // sqrt(a) = isqrt(a 4^s) / 2^s with a 4^s in [2^28, 2^30): 15 significant bits.
    uint32_t n = accel;
    uint8_t s = 0;
    while (n < (1UL << 28)) {
        n <<= 2;
        ++s;
    }
    const uint32_t r = isqrt32(n);
    // c0 = 256 f sqrt(2) 2^s / r = ((2 * 256 f sqrt(2)) / r) 2^s / 2, exact to ~1e-5.
    uint32_t q = C0_NUM_X2 / r;
    return (q << s) >> 1;
}

namespace {
// c0 / (sqrt(p) + sqrt(q)) for p >= 1, p >= q, p < 2^30: both roots of p 4^s and q 4^s
// (>= 2^28), so each has 14+ significant bits, then one 32-bit division.
uint32_t c0_over_root_sum(uint32_t c0_q8, uint32_t p, uint32_t q) {
    uint8_t s = 0;
    while (s < 14 && (p << 2) < (1UL << 30) && p < (1UL << 28)) {
        p <<= 2;
        q <<= 2;
        ++s;
    }
    const uint32_t sum = isqrt32(p) + isqrt32(q);  // (sqrt(p) + sqrt(q)) 2^s
    uint32_t inv = (1UL << (16 + s)) / sum;        // 2^16 / (sqrt(p) + sqrt(q))
    if (inv > 65535UL) inv = 65535UL;
    return mul_q16(c0_q8, static_cast<uint16_t>(inv));
}
}  // namespace

StepPlanner::StepPlanner()
    : total_(0), index_(0), remaining_(0), cruise_q8_(256), c0_q8_(256), c0_rs_(0), cross_k_(NONE), special_q8_(0),
      stopping_(false),
      stop_c0_q8_(256), stop_c0_rs_(0), stop_floor_q8_(0), carry_q8_(0) {}

void StepPlanner::begin(uint32_t steps, uint32_t rate, uint32_t accel) {
    if (rate == 0) rate = 1;
    if (accel == 0) accel = 1;
    total_ = remaining_ = steps;
    index_ = 0;
    carry_q8_ = 0;
    stopping_ = false;
    cruise_q8_ = F_Q8 / rate;
    if (cruise_q8_ < 256) cruise_q8_ = 256;
    c0_q8_ = c0_q8(accel);
    c0_rs_ = mul_q16(c0_q8_, INV_SQRT2_Q16);
    cross_k_ = NONE;
    special_q8_ = 0;
    if (steps == 0) return;
    const uint32_t v = rate > 65535UL ? 65535UL : rate;
    const uint32_t two_a = accel > 0x7FFFFFFFUL ? 0xFFFFFFFEUL : 2 * accel;
    const uint32_t v2 = v * v;
    const uint32_t x = v2 / two_a;  // the ramp reaches the rate at s_a = x + f steps
    if (steps > v2 / accel) {  // steps a > v^2: the rate is reached
        // Trapezoid. The step from position x to x + 1 leaves the ramp: it lasts
        // (1 - f) / v + c0 f / (sqrt(x + f) + sqrt(x)), f = (v^2 mod 2a) / 2a.
        const uint32_t rem = v2 % two_a;
        const uint32_t g = two_a > (1UL << 20) ? rem / (two_a >> 12) : (rem << 12) / two_a;  // f in 1/4096
        uint32_t t = mul_q16(cruise_q8_, static_cast<uint16_t>((4096 - g) << 4));
        if (g > 0) {
            uint32_t ramp_part;
            if (x < (1UL << 18)) {
                // c0 (g/4096) / (sqrt(x + g/4096) + sqrt(x)) = c0 (g/64) / (sqrt(4096x + g) + sqrt(4096x))
                ramp_part = mul_q16(c0_over_root_sum(c0_q8_, 4096 * x + g, 4096 * x), static_cast<uint16_t>(g << 4))
                            << 6;
            } else {
                ramp_part = mul_q16(ramp_q8(c0_q8_, c0_rs_, x), static_cast<uint16_t>(g << 4));
            }
            t += ramp_part;
        }
        cross_k_ = x;
        special_q8_ = t;
        // When that step is also the middle one it holds both ramp ends: 2 T - 1/v.
        if (steps == 2 * x + 1) special_q8_ = 2 * t > cruise_q8_ ? 2 * t - cruise_q8_ : cruise_q8_;
    } else if (steps & 1) {
        // Odd triangle: the middle step m straddles the peak; it lasts
        // c0 (sqrt(4m + 2) - sqrt(4m)) = 2 c0 / (sqrt(4m + 2) + sqrt(4m)).
        const uint32_t m = (steps - 1) / 2;
        special_q8_ = m < (1UL << 27) ? 2 * c0_over_root_sum(c0_q8_, 4 * m + 2, 4 * m) : ramp_q8(c0_q8_, c0_rs_, m);
    }
}

uint32_t StepPlanner::ramp_q8(uint32_t c0, uint32_t c0_rs, uint32_t k) {
    if (k == 0) return c0;
    if (k < TABLE_K) {
        const uint16_t mant = flash_u16(&RAMP_MANT[k]);
        return mul_q16(c0, mant) >> flash_u8(&RAMP_SHIFT[k]);
    }
    // R(k) = rsqrt(x) / sqrt(2), x = 2k + 1 = m 4^e with m in [1, 4); c0_rs = c0 / sqrt(2).
    // m in 1/2^14 is x shifted right by 2e - 14 (even): found with byte shifts and at most
    // three 2-bit steps, since variable 32-bit shifts are loops on the AVR.
    uint32_t x = 2 * k + 1;
    int8_t s = 0;  // right shift applied to x
    if (x >= (1UL << 24)) {
        x >>= 8;
        s = 8;
    }
    if (x >= (1UL << 16)) {
        x >>= 8;
        s = static_cast<int8_t>(s + 8);
    }
    while (x < (1UL << 14)) {
        x <<= 2;
        s = static_cast<int8_t>(s - 2);
    }
    const uint16_t m_q14 = static_cast<uint16_t>(x);
    uint8_t e = static_cast<uint8_t>((s + 14) / 2);
    const uint16_t idx = static_cast<uint16_t>((m_q14 >> 8) - 64);
    const uint8_t frac = static_cast<uint8_t>(m_q14 & 0xFF);
    const uint16_t lo = flash_u16(&RSQRT_Q16[idx]);
    const uint16_t hi = flash_u16(&RSQRT_Q16[idx + 1]);
    const uint16_t rs = static_cast<uint16_t>(lo - ((static_cast<uint16_t>(lo - hi) * static_cast<uint32_t>(frac)) >> 8));
    uint32_t r = mul_q16(c0_rs, rs);
    if (e >= 8) {
        r >>= 8;
        e = static_cast<uint8_t>(e - 8);
    }
    while (e--) r >>= 1;
    return r;
}

uint32_t StepPlanner::interval_q8(uint32_t index) const {
    uint32_t k = index;
    const uint32_t mirror = total_ - 1 - index;
    if (mirror < k) k = mirror;
    uint32_t q8;
    if (cross_k_ != NONE) {
        if (k > cross_k_) return cruise_q8_;
        q8 = k == cross_k_ ? special_q8_ : ramp_q8(c0_q8_, c0_rs_, k);
    } else if (special_q8_ != 0 && index == total_ / 2) {
        q8 = special_q8_;
    } else {
        q8 = ramp_q8(c0_q8_, c0_rs_, k);
    }
    return q8 < cruise_q8_ ? cruise_q8_ : q8;
}

uint32_t StepPlanner::next_interval() {
    if (remaining_ == 0) return 0;
    uint32_t q8;
    if (stopping_) {
        q8 = ramp_q8(stop_c0_q8_, stop_c0_rs_, remaining_ - 1);
        if (q8 < stop_floor_q8_) q8 = stop_floor_q8_;
    } else {
        q8 = interval_q8(index_);
    }
    const uint32_t sum = q8 + carry_q8_;
    carry_q8_ = static_cast<uint8_t>(sum & 0xFF);
    ++index_;
    --remaining_;
    return sum >> 8;
}

namespace {
// Ramp steps from this distance on go out in groups, each step's interval on the chord
// between the group's exact end points: with G <= k / 16 the chord is within
// (3/32) (G/k)^2 < 4e-4 of the exact interval (R is convex), a fraction of a tick where
// steps are fast, and the main loop computes two intervals per group, not one per step.
const uint32_t GROUP_MIN_K = 64;
const uint8_t GROUP_MAX = 64;

// Largest power of two G <= GROUP_MAX with G * 16 <= k (1 below GROUP_MIN_K), and its log2.
uint8_t group_for(uint32_t k, uint8_t& shift) {
    shift = 0;
    if (k < GROUP_MIN_K) return 1;
    uint8_t g = 4;
    shift = 2;
    while (g < GROUP_MAX && static_cast<uint32_t>(g) * 32 <= k) {
        g = static_cast<uint8_t>(g << 1);
        ++shift;
    }
    return g;
}

// For a group counting down from k: its far end k - G must still have G * 16 <= k - G.
uint8_t group_down_for(uint32_t k, uint8_t& shift) {
    uint8_t g = group_for(k, shift);
    while (g > 1 && static_cast<uint32_t>(g) * 17 > k) {
        g = static_cast<uint8_t>(g >> 1);
        --shift;
    }
    if (g < 4) {  // groups start at 4 steps
        g = 1;
        shift = 0;
    }
    return g;
}

// The slope (b - a) / 2^shift as an int16, or false when it does not fit.
bool slope_q8(uint32_t a, uint32_t b, uint8_t shift, int16_t& add) {
    const int32_t d = static_cast<int32_t>(b - a) >> shift;
    if (d > 32767 || d < -32768) return false;
    add = static_cast<int16_t>(d);
    return true;
}
}  // namespace

uint8_t StepPlanner::next_run(uint32_t& q8, int16_t& add, uint8_t max_count) {
    add = 0;
    if (remaining_ == 0 || max_count == 0) return 0;
    uint8_t n = 1;
    uint8_t shift = 0;
    if (stopping_) {
        // k = remaining - 1 counts down to 0; a group needs its far end (k - G) >= 0.
        const uint32_t k = remaining_ - 1;
        q8 = ramp_q8(stop_c0_q8_, stop_c0_rs_, k);
        uint8_t g = group_down_for(k, shift);
        if (g > max_count || g > k) g = 1;
        if (g > 1 && q8 >= stop_floor_q8_ &&
            slope_q8(q8, ramp_q8(stop_c0_q8_, stop_c0_rs_, k - g), shift, add))
            n = g;
        if (q8 < stop_floor_q8_) q8 = stop_floor_q8_;
    } else if (cross_k_ != NONE && index_ > cross_k_ && total_ - 1 - index_ > cross_k_) {
        // Cruise: steps with index < total - 1 - cross_k all last cruise_q8_.
        const uint32_t cruise_left = total_ - 1 - cross_k_ - index_;
        n = cruise_left < max_count ? static_cast<uint8_t>(cruise_left) : max_count;
        q8 = cruise_q8_;
    } else {
        q8 = interval_q8(index_);
        const uint32_t mirror = total_ - 1 - index_;
        if (index_ < mirror) {  // accelerating: k = index counts up
            const uint8_t g = group_for(index_, shift);
            // the whole group before the middle, its far end (k + G) on the ramp
            if (g > 1 && g <= max_count && 2 * (index_ + g - 1) < total_ - 1 &&
                (cross_k_ == NONE || index_ + g <= cross_k_) &&
                slope_q8(q8, ramp_q8(c0_q8_, c0_rs_, index_ + g), shift, add))
                n = g;
        } else if (index_ > mirror && (cross_k_ == NONE || mirror < cross_k_)) {  // decelerating: k counts down
            const uint8_t g = group_down_for(mirror, shift);
            if (g > 1 && g <= max_count && g <= mirror &&
                slope_q8(q8, ramp_q8(c0_q8_, c0_rs_, mirror - g), shift, add))
                n = g;
        }
    }
    if (n == 1) add = 0;
    index_ += n;
    remaining_ -= n;
    return n;
}

void StepPlanner::rewind(uint32_t steps) {
    if (steps > index_) steps = index_;
    index_ -= steps;
    remaining_ += steps;
}

uint32_t StepPlanner::stop(uint32_t a_max) {
    if (remaining_ == 0 || stopping_) return remaining_;
    if (index_ == 0) {  // not started: nothing moves
        remaining_ = 0;
        return 0;
    }
    if (a_max == 0) a_max = 1;
    const uint32_t last_q8 = interval_q8(index_ - 1);
    // v = f / interval; n = v^2 / 2 a_max, all within 32 bits (v <= 50000 steps/s).
    const uint32_t v = F_Q8 / (last_q8 < 256 ? 256 : last_q8);
    const uint32_t n = v * v / (2 * a_max);
    if (n >= remaining_) return remaining_;  // the planned deceleration ends sooner
    stopping_ = true;
    stop_c0_q8_ = c0_q8(a_max);
    stop_c0_rs_ = mul_q16(stop_c0_q8_, INV_SQRT2_Q16);
    stop_floor_q8_ = last_q8;
    remaining_ = n;
    return n;
}

}  // namespace fw
