// Firmware entry: bring up the board, boot the protocol device, poll it forever.
#include "board/avr_board.h"
#include "core/device.h"

namespace {
board::AvrBoard g_board;
fw::Device g_device(g_board);
}  // namespace

int main() {
    g_board.init();
    g_device.boot();
    g_board.start_watchdog();
    for (;;) g_device.poll();
}
