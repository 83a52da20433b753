// See plant_link.h.
#include "plant_link.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

struct plant_link {
    int fd;
};

static int write_all(int fd, const void *buf, size_t n) {
    const uint8_t *p = buf;
    while (n) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return -1;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

static int read_all(int fd, void *buf, size_t n) {
    uint8_t *p = buf;
    while (n) {
        ssize_t r = read(fd, p, n);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return -1;
        p += r;
        n -= (size_t)r;
    }
    return 0;
}

struct plant_link *plant_connect(const char *path, char *err, size_t errlen) {
    struct sockaddr_un addr;
    memset(&addr, 0, sizeof addr);
    addr.sun_family = AF_UNIX;
    if (strlen(path) >= sizeof addr.sun_path) {
        snprintf(err, errlen, "plant socket path too long: %s", path);
        return NULL;
    }
    strcpy(addr.sun_path, path);
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    if (fd < 0 || connect(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        snprintf(err, errlen, "cannot connect to the plant at %s: %s", path, strerror(errno));
        if (fd >= 0) close(fd);
        return NULL;
    }
    if (write_all(fd, "TSAPLNT1", 8) < 0) {
        snprintf(err, errlen, "plant at %s closed the connection", path);
        close(fd);
        return NULL;
    }
    struct plant_link *p = calloc(1, sizeof *p);
    p->fd = fd;
    return p;
}

int plant_wait_start(struct plant_link *p) {
    uint8_t c = 0;
    if (read_all(p->fd, &c, 1) < 0 || c != 'G') return -1;
    return 0;
}

static void put_u32(uint8_t *b, uint32_t v) {
    for (int i = 0; i < 4; ++i) b[i] = (uint8_t)(v >> (8 * i));
}

static void put_f64(uint8_t *b, double v) {
    uint64_t u;
    memcpy(&u, &v, 8);
    for (int i = 0; i < 8; ++i) b[i] = (uint8_t)(u >> (8 * i));
}

int plant_query(struct plant_link *p, char kind, double t_s, int32_t steps, int moving, double heater_duty,
                int32_t *counts, uint8_t *flags) {
    uint8_t req[24] = {0};
    req[0] = (uint8_t)kind;
    req[1] = moving ? 1 : 0;
    put_u32(req + 4, (uint32_t)steps);
    put_f64(req + 8, t_s);
    put_f64(req + 16, heater_duty);
    uint8_t rep[8];
    if (write_all(p->fd, req, sizeof req) < 0 || read_all(p->fd, rep, sizeof rep) < 0) return -1;
    *counts = (int32_t)((uint32_t)rep[0] | (uint32_t)rep[1] << 8 | (uint32_t)rep[2] << 16 | (uint32_t)rep[3] << 24);
    *flags = rep[4];
    return 0;
}

void plant_close(struct plant_link *p) {
    if (!p) return;
    close(p->fd);
    free(p);
}
