// Flash images from Intel hex files: the Mega's own bootloader as Debian ships it
// (stk500boot_v2_mega2560.hex) and applications as avr-objcopy writes them.
//
// Contract. flash_image_is_elf() tells an ELF file (by its magic) from anything else.
// flash_image_load_hex() checks every record (colon, hex digits, length, checksum) and
// writes the data records into the AVR's flash at their addresses (record types 02 and
// 04 set the upper address bits; 03 and 05, start addresses, are ignored as the chip
// ignores them; 01 ends the file). Nothing is written unless the whole file is valid
// and fits below `limit` (bytes); returns the lowest address written, or -1 with `err`
// naming the file, the line and what is wrong.
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

int flash_image_is_elf(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    unsigned char magic[4] = {0};
    const size_t n = fread(magic, 1, 4, f);
    fclose(f);
    return n == 4 && !memcmp(magic, "\x7f" "ELF", 4);
}

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
}

long flash_image_load_hex(avr_t *avr, const char *path, uint32_t limit, char *err, size_t errlen) {
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, errlen, "cannot open %s", path);
        return -1;
    }
    uint8_t *image = malloc(limit);
    uint8_t *used = calloc(limit, 1);
    char line[600];
    uint32_t upper = 0, lowest = UINT32_MAX;
    int lineno = 0, ended = 0;
    const char *problem = NULL;
    while (!problem && !ended && fgets(line, sizeof line, f)) {
        ++lineno;
        size_t len = strcspn(line, "\r\n");
        if (len == 0) continue;
        uint8_t rec[260];
        if (line[0] != ':' || len % 2 == 0 || len < 11 || (len - 1) / 2 > sizeof rec) {
            problem = "not an Intel hex record";
            break;
        }
        const size_t nbytes = (len - 1) / 2;
        for (size_t i = 0; i < nbytes && !problem; ++i) {
            const int hi = hexval(line[1 + 2 * i]), lo = hexval(line[2 + 2 * i]);
            if (hi < 0 || lo < 0) problem = "a character that is not a hex digit";
            rec[i] = (uint8_t)(hi << 4 | lo);
        }
        if (problem) break;
        uint8_t sum = 0;
        for (size_t i = 0; i < nbytes; ++i) sum = (uint8_t)(sum + rec[i]);
        if (rec[0] + 5u != nbytes) problem = "a record length that does not match the line";
        else if (sum != 0) problem = "a bad checksum";
        if (problem) break;
        const uint32_t offset = (uint32_t)rec[1] << 8 | rec[2];
        switch (rec[3]) {
        case 0:
            for (uint32_t i = 0; i < rec[0]; ++i) {
                const uint32_t a = upper + offset + i;
                if (a >= limit) {
                    problem = "data beyond the flash it may fill";
                    break;
                }
                image[a] = rec[4 + i];
                used[a] = 1;
                if (a < lowest) lowest = a;
            }
            break;
        case 1: ended = 1; break;
        case 2: upper = ((uint32_t)rec[4] << 8 | rec[5]) << 4; break;
        case 4: upper = ((uint32_t)rec[4] << 8 | rec[5]) << 16; break;
        case 3: case 5: break;
        default: problem = "an unknown record type";
        }
    }
    fclose(f);
    if (!problem && !ended) problem = "no end-of-file record (a truncated file?)";
    if (!problem && lowest == UINT32_MAX) problem = "no data";
    if (problem) {
        snprintf(err, errlen, "%s line %d: %s", path, lineno, problem);
    } else {
        for (uint32_t a = 0; a < limit; ++a)
            if (used[a]) avr->flash[a] = image[a];
    }
    free(image);
    free(used);
    return problem ? -1 : (long)lowest;
}
