/* Hardware-independent protocol and safety rules; see ac_protocol.h. */
#include "ac_protocol.h"

#include <string.h>

#ifdef __AVR__
#include <util/crc16.h>
#endif

uint16_t ac_crc16_update(uint16_t crc, uint8_t byte) {
#ifdef __AVR__
    return _crc_xmodem_update(crc, byte); /* avr-libc's inline asm version of the code below */
#else
    crc ^= (uint16_t)byte << 8;
    for (uint8_t i = 0; i < 8; i++) crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    return crc;
#endif
}

/* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final XOR. */
uint16_t ac_crc16(const uint8_t *data, uint8_t len) {
    uint16_t crc = 0xFFFF;
    while (len--) crc = ac_crc16_update(crc, *data++);
    return crc;
}

uint8_t ac_cobs_encode(const uint8_t *in, uint8_t len, uint8_t *out) {
    uint8_t code_at = 0, n = 1, code = 1;
    for (uint8_t i = 0; i < len; i++) {
        if (in[i] == 0) {
            out[code_at] = code;
            code_at = n++;
            code = 1;
        } else {
            out[n++] = in[i];
            code++; /* frames are < 254 bytes: no 0xFF block split needed */
        }
    }
    out[code_at] = code;
    return n;
}

int16_t ac_cobs_decode(const uint8_t *in, uint8_t len, uint8_t *out) {
    /* Mirrors the Python `cobs` package: a code byte claiming more bytes than remain is an error. */
    uint8_t i = 0, n = 0;
    while (i < len) {
        uint8_t code = in[i++];
        if (code == 0) return -1;
        uint16_t end = (uint16_t)i + code - 1;
        if (end > len) return -1;
        while (i < end) {
            if (in[i] == 0) return -1;
            out[n++] = in[i++];
        }
        if (i < len && code < 0xFF) out[n++] = 0;
    }
    return n;
}

static void put16(uint8_t *p, uint16_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put32(uint8_t *p, uint32_t v) {
    put16(p, (uint16_t)v);
    put16(p + 2, (uint16_t)(v >> 16));
}

static uint16_t get16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }

static uint32_t get32(const uint8_t *p) { return get16(p) | ((uint32_t)get16(p + 2) << 16); }

static uint8_t wrap(uint8_t *body, uint8_t len, uint8_t *wire) {
    put16(body + len, ac_crc16(body, len));
    uint8_t n = ac_cobs_encode(body, (uint8_t)(len + 2), wire);
    wire[n++] = 0;
    return n;
}

uint8_t ac_pack_telemetry(const ac_telemetry_t *t, uint8_t *wire) {
    uint8_t body[AC_TELEMETRY_BODY + 2];
    body[0] = AC_TELEMETRY;
    put16(body + 1, t->seq);
    put32(body + 3, t->t_us);
    put32(body + 7, t->left);
    put32(body + 11, t->right);
    body[15] = t->status;
    return wrap(body, AC_TELEMETRY_BODY, wire);
}

uint8_t ac_pack_command(const ac_command_t *c, uint8_t *wire) {
    uint8_t body[AC_COMMAND_BODY + 2];
    body[0] = AC_COMMAND;
    put16(body + 1, c->seq);
    put16(body + 3, c->ack_seq);
    put16(body + 5, c->longitudinal_mv);
    put16(body + 7, c->angular_mv);
    body[9] = c->flags;
    return wrap(body, AC_COMMAND_BODY, wire);
}

void ac_rx_init(ac_rx_t *rx) { memset(rx, 0, sizeof *rx); }

uint32_t ac_rx_bad_frames(const ac_rx_t *rx) {
    const ac_rx_stats_t *s = &rx->stats;
    return s->bad_crc + s->bad_cobs + s->bad_length + s->unknown_type + s->oversize;
}

/* Parse one encoded chunk; errors are counted only when count is set (tail retries are not). */
static uint8_t parse(ac_rx_t *rx, const uint8_t *chunk, uint8_t len, ac_frame_t *out, uint8_t count) {
    uint8_t raw[AC_MAX_FRAME];
    ac_rx_stats_t *s = &rx->stats;
    int16_t n = ac_cobs_decode(chunk, len, raw);
    if (n < 0) {
        if (count) s->bad_cobs++;
        return 0;
    }
    if (n < 3) {
        if (count) s->bad_length++;
        return 0;
    }
    uint8_t body_len = (uint8_t)(n - 2);
    if (ac_crc16(raw, body_len) != get16(raw + body_len)) {
        if (count) s->bad_crc++;
        return 0;
    }
    if (raw[0] == AC_TELEMETRY) {
        if (body_len != AC_TELEMETRY_BODY) {
            if (count) s->bad_length++;
            return 0;
        }
        out->type = AC_TELEMETRY;
        out->tel.seq = get16(raw + 1);
        out->tel.t_us = get32(raw + 3);
        out->tel.left = get32(raw + 7);
        out->tel.right = get32(raw + 11);
        out->tel.status = raw[15];
        return 1;
    }
    if (raw[0] == AC_COMMAND) {
        if (body_len != AC_COMMAND_BODY) {
            if (count) s->bad_length++;
            return 0;
        }
        out->type = AC_COMMAND;
        out->cmd.seq = get16(raw + 1);
        out->cmd.ack_seq = get16(raw + 3);
        out->cmd.longitudinal_mv = get16(raw + 5);
        out->cmd.angular_mv = get16(raw + 7);
        out->cmd.flags = raw[9];
        return 1;
    }
    if (count) s->unknown_type++;
    return 0;
}

uint8_t ac_rx_byte(ac_rx_t *rx, uint8_t byte, ac_frame_t *out) {
    ac_rx_stats_t *s = &rx->stats;
    if (byte != 0) {
        if (rx->len == AC_MAX_FRAME) { /* a run with no delimiter: drop it */
            s->oversize++;
            s->garbage_bytes += AC_MAX_FRAME + 1;
            rx->len = 0;
            return 0;
        }
        rx->buf[rx->len++] = byte;
        return 0;
    }
    uint8_t len = rx->len;
    rx->len = 0;
    if (len == 0) return 0; /* back-to-back delimiters: idle line */
    if (parse(rx, rx->buf, len, out, 1)) {
        s->frames++;
        return 1;
    }
    /* Garbage glued to the front of a frame: frame sizes are fixed, so try the chunk's tail. */
    static const uint8_t sizes[2] = {AC_TELEMETRY_WIRE - 1, AC_COMMAND_WIRE - 1};
    for (uint8_t i = 0; i < 2; i++) {
        if (len > sizes[i] && parse(rx, rx->buf + len - sizes[i], sizes[i], out, 0)) {
            s->garbage_bytes += (uint32_t)(len - sizes[i]);
            s->frames++;
            return 1;
        }
    }
    s->garbage_bytes += (uint32_t)len + 1;
    return 0;
}

void ac_fw_init(ac_fw_t *fw, uint16_t seq_start) {
    memset(fw, 0, sizeof *fw);
    fw->longitudinal_mv = fw->angular_mv = AC_NEUTRAL_MV; /* neutral from the first instruction */
    fw->status = AC_ST_BOOT | AC_ST_HOST_TIMEOUT;
    fw->booting = fw->timed_out = 1;
    fw->seq = seq_start;
}

static void neutral(ac_fw_t *fw) {
    fw->longitudinal_mv = fw->angular_mv = AC_NEUTRAL_MV;
    fw->status &= (uint8_t)~AC_ST_OUTPUT_ENABLED;
}

static uint8_t in_window(uint16_t mv) { return mv >= AC_MIN_MV && mv <= AC_MAX_MV; }

static void on_command(ac_fw_t *fw, const ac_command_t *c, uint32_t now_us) {
    fw->counters.host_frames++;
    fw->have_host = 1;
    fw->last_host_us = now_us;
    fw->last_ack_seq = c->ack_seq;
    if (fw->booting && now_us < AC_BOOT_US) return; /* host contact, but not applied */
    if (!in_window(c->longitudinal_mv) || !in_window(c->angular_mv)) {
        fw->counters.rejected_commands++;
        fw->status |= AC_ST_CMD_REJECTED;
        neutral(fw);
        return;
    }
    fw->status &= (uint8_t)~AC_ST_CMD_REJECTED;
    if (c->flags & AC_FL_ENABLE) {
        fw->longitudinal_mv = c->longitudinal_mv;
        fw->angular_mv = c->angular_mv;
        fw->status |= AC_ST_OUTPUT_ENABLED;
    } else {
        neutral(fw);
    }
}

void ac_fw_rx_byte(ac_fw_t *fw, uint8_t byte, uint32_t now_us) {
    ac_frame_t f;
    if (ac_rx_byte(&fw->rx, byte, &f)) {
        if (f.type == AC_COMMAND) {
            on_command(fw, &f.cmd, now_us);
        } else { /* valid CRC, wrong direction */
            fw->rx.stats.unknown_type++;
        }
    }
    fw->counters.host_bad_frames = ac_rx_bad_frames(&fw->rx);
}

void ac_fw_watch(ac_fw_t *fw, uint32_t now_us) {
    if (fw->booting && now_us < AC_BOOT_US) {
        fw->status |= AC_ST_BOOT;
        neutral(fw);
    } else {
        fw->booting = 0; /* latched, so the clock wrapping after 71 min cannot re-enter boot */
        fw->status &= (uint8_t)~AC_ST_BOOT;
    }
    /* Signed difference: wrap-safe; have_host is dropped on timeout, so a host silent for
     * longer than the clock's wrap can never look fresh again. */
    uint8_t timed_out = !fw->have_host || (int32_t)(now_us - fw->last_host_us) > (int32_t)AC_WATCHDOG_US;
    if (timed_out) {
        if (!fw->timed_out) fw->counters.host_timeouts++;
        fw->have_host = 0;
        fw->status |= AC_ST_HOST_TIMEOUT;
        neutral(fw);
    } else {
        fw->status &= (uint8_t)~AC_ST_HOST_TIMEOUT;
    }
    fw->timed_out = timed_out;
}

uint8_t ac_fw_tick(ac_fw_t *fw, uint32_t now_us, uint32_t left, uint32_t right,
                   uint8_t extra_status, uint8_t *wire) {
    ac_fw_watch(fw, now_us);
    if (fw->seq_started) fw->seq++;
    fw->seq_started = 1;
    fw->counters.telemetry_frames++;
    ac_telemetry_t t = {fw->seq, now_us, left, right, (uint8_t)(fw->status | extra_status)};
    return ac_pack_telemetry(&t, wire);
}
