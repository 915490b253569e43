/* Chair <-> host serial protocol and the firmware's safety rules, hardware-independent.
 *
 * Spec: docs/arduino-protocol.md. Python twin: services/autochair/protocol/arduino.py (framing)
 * and services/autochair/sim/chair/firmware.py (rules); tests/test_firmware_protocol.py checks this
 * code byte for byte against both. No AVR registers here: time is passed in (µs, u32 wrapping),
 * so the same file builds for the ATmega328P and for host unit tests.
 */
#ifndef AC_PROTOCOL_H
#define AC_PROTOCOL_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define AC_TELEMETRY 0x01 /* chair -> host */
#define AC_COMMAND 0x02   /* host -> chair */
#define AC_TELEMETRY_BODY 16
#define AC_COMMAND_BODY 10
#define AC_TELEMETRY_WIRE 20 /* body + CRC + COBS overhead + 0x00 delimiter */
#define AC_COMMAND_WIRE 14
#define AC_MAX_FRAME 64 /* longest encoded chunk accepted before declaring garbage */

/* Telemetry status bits. */
#define AC_ST_OUTPUT_ENABLED 0x01
#define AC_ST_HOST_TIMEOUT 0x02
#define AC_ST_BOOT 0x04
#define AC_ST_ENCODER_FAULT 0x08
#define AC_ST_CMD_REJECTED 0x10

#define AC_FL_ENABLE 0x01

#define AC_NEUTRAL_MV 2500
#define AC_MIN_MV 1100
#define AC_MAX_MV 3900
#define AC_WATCHDOG_US 200000UL /* no valid host frame this long -> neutral */
#define AC_BOOT_US 1000000UL    /* neutral, commands not applied, after reset */

typedef struct {
    uint16_t seq;
    uint32_t t_us;
    uint32_t left;
    uint32_t right;
    uint8_t status;
} ac_telemetry_t;

typedef struct {
    uint16_t seq;
    uint16_t ack_seq;
    uint16_t longitudinal_mv;
    uint16_t angular_mv;
    uint8_t flags;
} ac_command_t;

typedef struct {
    uint8_t type; /* AC_TELEMETRY or AC_COMMAND: which member is valid */
    ac_telemetry_t tel;
    ac_command_t cmd;
} ac_frame_t;

/* Same counters, same meaning as autochair.protocol.arduino.DecoderStats. */
typedef struct {
    uint32_t frames;
    uint32_t bad_crc;
    uint32_t bad_cobs;
    uint32_t bad_length;
    uint32_t unknown_type;
    uint32_t oversize;
    uint32_t garbage_bytes;
} ac_rx_stats_t;

/* Incremental receiver: one byte at a time, resynchronising on 0x00. */
typedef struct {
    uint8_t buf[AC_MAX_FRAME];
    uint8_t len;
    ac_rx_stats_t stats;
} ac_rx_t;

typedef struct {
    uint32_t host_frames;       /* valid Command frames received */
    uint32_t host_bad_frames;   /* rejected frames (CRC, COBS, length, type, oversize) */
    uint32_t host_timeouts;     /* transitions into ST_HOST_TIMEOUT after host contact */
    uint32_t rejected_commands; /* valid frames with voltages outside the window */
    uint32_t telemetry_frames;
} ac_fw_counters_t;

/* The firmware's rules (boot, watchdog, window) as a state machine. */
typedef struct {
    ac_rx_t rx;
    ac_fw_counters_t counters;
    uint16_t longitudinal_mv; /* what the DAC must drive now */
    uint16_t angular_mv;
    uint8_t status;
    uint8_t booting;   /* cleared at the first tick at or after AC_BOOT_US */
    uint8_t have_host; /* a valid host frame within the watchdog window */
    uint8_t timed_out;
    uint8_t seq_started;
    uint16_t seq;
    uint16_t last_ack_seq;
    uint32_t last_host_us;
} ac_fw_t;

uint16_t ac_crc16(const uint8_t *data, uint8_t len);
uint16_t ac_crc16_update(uint16_t crc, uint8_t byte);
/* COBS-encode len (<= 253) bytes; returns the encoded length (len + 1), no delimiter. */
uint8_t ac_cobs_encode(const uint8_t *in, uint8_t len, uint8_t *out);
/* Decode a 0x00-free chunk; returns the decoded length or -1 (truncated code block). */
int16_t ac_cobs_decode(const uint8_t *in, uint8_t len, uint8_t *out);

/* Whole wire frames (COBS(body + CRC) + 0x00); return the byte count (20 / 14). */
uint8_t ac_pack_telemetry(const ac_telemetry_t *t, uint8_t *wire);
uint8_t ac_pack_command(const ac_command_t *c, uint8_t *wire);

void ac_rx_init(ac_rx_t *rx);
/* Feed one byte; returns 1 and fills *out when it completes a valid frame. */
uint8_t ac_rx_byte(ac_rx_t *rx, uint8_t byte, ac_frame_t *out);
uint32_t ac_rx_bad_frames(const ac_rx_t *rx);

void ac_fw_init(ac_fw_t *fw, uint16_t seq_start);
/* One byte from the host, arrived at MCU time now_us. */
void ac_fw_rx_byte(ac_fw_t *fw, uint8_t byte, uint32_t now_us);
/* Apply the boot and watchdog rules at now_us (every tick, and between ticks so the watchdog's
 * resolution does not depend on the frame period). */
void ac_fw_watch(ac_fw_t *fw, uint32_t now_us);
/* Apply boot and watchdog rules at now_us and write one telemetry frame into wire (returns 20).
 * extra_status is OR-ed into this frame's status (e.g. AC_ST_ENCODER_FAULT). */
uint8_t ac_fw_tick(ac_fw_t *fw, uint32_t now_us, uint32_t left, uint32_t right,
                   uint8_t extra_status, uint8_t *wire);

#ifdef __cplusplus
}
#endif
#endif
