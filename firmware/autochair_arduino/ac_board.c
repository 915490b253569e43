/* ATmega328P board layer. Pins (Arduino names):
 *   A0/A1 = left encoder A/B, A2/A3 = right encoder A/B   (PC0..PC3, pin-change interrupt PCINT1)
 *   D10 = MCP4922 /CS, D11 = MOSI -> SDI, D13 = SCK, D9 = MCP4922 /LDAC   (hardware SPI)
 *   D8  = joystick relay driver (high = DAC drives the chair; low / MCU off = real joystick)
 *   D0/D1 = UART to the host (USB serial on Uno/Nano)
 * Timer1 (CTC, /8) gives the frame tick (AC_FRAME_US, 100 Hz) and the µs clock; its compare B
 * wakes the loop in mid-frame for a watchdog check. Timer0 is left to Arduino. */
#include "ac_config.h"
#include "ac_board.h"
#include "ac_protocol.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>

#define TIMER_TOP ((uint16_t)(AC_FRAME_US * 2 - 1)) /* Timer1 at F_CPU/8 = 2 counts per µs */
#define RX_SIZE 128                                 /* powers of two: cheap index masking */
#define TX_SIZE 128

/* --- encoders: both on port C, one pin-change ISR ------------------------------------------ */
/* index = previous AB << 2 | current AB, AB = A | B << 1. A leading B counts +1.
 * 2 marks an impossible step (both lines changed): a missed edge, reported as ST_ENCODER_FAULT. */
static const int8_t QDEC[16] = {0, 1, -1, 2, -1, 0, 2, 1, 1, 2, 0, -1, 2, -1, 1, 0};
static volatile uint32_t enc_left, enc_right;
static volatile uint8_t enc_prev, enc_fault;

ISR(PCINT1_vect) {
    uint8_t now = PINC & 0x0F, prev = enc_prev;
    int8_t dl = QDEC[((prev & 3) << 2) | (now & 3)];
    int8_t dr = QDEC[(prev & 0x0C) | (now >> 2)];
    enc_prev = now;
    if (dl == 2) enc_fault = 1; else enc_left += (AC_LEFT_INVERT ? -dl : dl);
    if (dr == 2) enc_fault = 1; else enc_right += (AC_RIGHT_INVERT ? -dr : dr);
}

/* --- clock and frame tick ----------------------------------------------------------------- */
static volatile uint32_t ticks;        /* Timer1 periods since reset */
static volatile uint8_t tick_pending;  /* frames due and not yet sent */
static volatile uint32_t snap_left, snap_right, snap_us;
static volatile uint8_t snap_fault;
static volatile uint8_t watch_pending; /* mid-frame watchdog check due */

ISR(TIMER1_COMPA_vect) {
    /* Sample counters on the timer, not in the main loop: t_us is exact and jitter-free. */
    ticks++;
    snap_us = ticks * AC_FRAME_US;
    snap_left = enc_left;
    snap_right = enc_right;
    snap_fault |= enc_fault;
    enc_fault = 0;
    if (tick_pending < 255) tick_pending++;
}

/* Mid-frame: the host watchdog is checked every half frame period (5 ms at 100 Hz), so the
 * output is neutral 200-205 ms after the last host frame, as it was with 5 ms frames. */
ISR(TIMER1_COMPB_vect) { watch_pending = 1; }

static uint32_t now_us(void) {
    uint8_t sreg = SREG;
    cli();
    uint32_t t = ticks;
    uint16_t c = TCNT1;
    if ((TIFR1 & _BV(OCF1A)) && c < TIMER_TOP / 2) t++; /* compare hit, ISR not yet run */
    SREG = sreg;
    return t * AC_FRAME_US + c / 2;
}

/* --- UART: interrupt-driven rings ----------------------------------------------------------- */
static volatile uint8_t rx_buf[RX_SIZE], rx_head, rx_tail;
static volatile uint8_t tx_buf[TX_SIZE], tx_head, tx_tail;
static volatile uint16_t rx_overruns, tx_drops;

ISR(USART_RX_vect) {
    uint8_t b = UDR0, next = (uint8_t)((rx_head + 1) & (RX_SIZE - 1));
    if (next == rx_tail) {
        rx_overruns++; /* the CRC will reject the damaged frame; the host sees it as lost */
        return;
    }
    rx_buf[rx_head] = b;
    rx_head = next;
}

ISR(USART_UDRE_vect) {
    if (tx_head == tx_tail) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx_buf[tx_tail];
    tx_tail = (uint8_t)((tx_tail + 1) & (TX_SIZE - 1));
}

static void uart_init(void) {
    UCSR0A = _BV(U2X0);
    UBRR0 = (uint16_t)((F_CPU / 8 / AC_BAUD) - 1); /* 115200 at 16 MHz: 16 -> 117647 (+2.1 %) */
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);             /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

/* Queue a whole frame or nothing: a partial frame would only cost the host a CRC error. */
static void uart_write(const uint8_t *data, uint8_t n) {
    uint8_t used = (uint8_t)((tx_head - tx_tail) & (TX_SIZE - 1));
    if (TX_SIZE - 1 - used < n) {
        tx_drops++; /* host sees the seq gap */
        return;
    }
    for (uint8_t i = 0; i < n; i++) {
        tx_buf[tx_head] = data[i];
        tx_head = (uint8_t)((tx_head + 1) & (TX_SIZE - 1));
    }
    UCSR0B |= _BV(UDRIE0);
}

/* --- MCP4922 dual 12-bit DAC on hardware SPI ------------------------------------------------- */
static void spi_init(void) {
    PORTB |= _BV(PB2) | _BV(PB1);                       /* /CS and /LDAC idle high */
    DDRB |= _BV(PB2) | _BV(PB3) | _BV(PB5) | _BV(PB1); /* /CS (also SS: must be output), MOSI, SCK, /LDAC */
    SPCR = _BV(SPE) | _BV(MSTR);                        /* mode 0, F_CPU/2 = 8 MHz (MCP4922: 20 MHz max) */
    SPSR = _BV(SPI2X);
}

static void spi_byte(uint8_t b) {
    SPDR = b;
    while (!(SPSR & _BV(SPIF))) {
    }
}

static void dac_channel(uint8_t channel_b, uint16_t mv) {
    uint32_t code = (uint32_t)mv * 4096UL / AC_DAC_VREF_MV;
    if (code > 4095) code = 4095;
    /* bit15 channel, bit14 buffered VREF, bit13 gain 1x, bit12 active */
    uint16_t word = (uint16_t)((channel_b ? 0x8000 : 0) | 0x7000 | code);
    PORTB &= (uint8_t)~_BV(PB2);
    spi_byte((uint8_t)(word >> 8));
    spi_byte((uint8_t)word);
    PORTB |= _BV(PB2);
}

/* Both channels are latched together by /LDAC, so the chair never sees half an update. */
static void dac_write(uint16_t longitudinal_mv, uint16_t angular_mv) {
    dac_channel(0, longitudinal_mv);
    dac_channel(1, angular_mv);
    PORTB &= (uint8_t)~_BV(PB1);
    __asm__ __volatile__("nop\n\tnop\n\t"); /* /LDAC low pulse >= 100 ns */
    PORTB |= _BV(PB1);
}

static uint16_t dac_long_mv = AC_NEUTRAL_MV, dac_ang_mv = AC_NEUTRAL_MV; /* last written */

/* Write the DAC when the firmware's output changed: a command or a neutral applies at once,
 * not at the next frame tick. */
static void dac_update(uint16_t longitudinal_mv, uint16_t angular_mv, uint8_t always) {
    if (!always && longitudinal_mv == dac_long_mv && angular_mv == dac_ang_mv) return;
    dac_write(longitudinal_mv, angular_mv);
    dac_long_mv = longitudinal_mv;
    dac_ang_mv = angular_mv;
}

/* --- application ------------------------------------------------------------------------- */
static ac_fw_t fw;

void ac_app_setup(void) {
    cli();
    MCUSR = 0;
    wdt_disable(); /* a watchdog reset leaves it running at 15 ms */
    ac_fw_init(&fw, 0);
    spi_init();
    dac_write(AC_NEUTRAL_MV, AC_NEUTRAL_MV); /* neutral before anything else can happen */
    DDRB |= _BV(PB0);
    PORTB |= _BV(PB0); /* relay: DAC (at neutral) now drives the joystick lines */

    DDRC &= (uint8_t)~0x0F;
    PORTC |= 0x0F; /* pull-ups for open-collector encoders */
    enc_prev = PINC & 0x0F;
    PCMSK1 = 0x0F;
    PCICR |= _BV(PCIE1);

    TCCR1A = 0;
    TCCR1B = _BV(WGM12); /* CTC first (stopped), then TOP, then the clock: F_CPU/8 */
    OCR1A = TIMER_TOP;
    OCR1B = TIMER_TOP / 2;
    TCNT1 = 0;
    TCCR1B |= _BV(CS11);
    TIFR1 = _BV(OCF1A) | _BV(OCF1B);
    TIMSK1 = _BV(OCIE1A) | _BV(OCIE1B);

    uart_init();
    set_sleep_mode(SLEEP_MODE_IDLE);
    wdt_enable(WDTO_60MS); /* a hung loop resets the MCU, and reset means neutral */
    sei();
}

void ac_app_loop_once(void) {
    wdt_reset();
    while (rx_tail != rx_head) {
        uint8_t b = rx_buf[rx_tail];
        rx_tail = (uint8_t)((rx_tail + 1) & (RX_SIZE - 1));
        ac_fw_rx_byte(&fw, b, now_us());
    }
    if (watch_pending) {
        watch_pending = 0;
        ac_fw_watch(&fw, now_us());
    }
    dac_update(fw.longitudinal_mv, fw.angular_mv, 0);
    if (tick_pending) {
        cli();
        uint32_t t = snap_us, l = snap_left, r = snap_right;
        uint8_t fault = snap_fault;
        snap_fault = 0;
        tick_pending = 0; /* a missed frame is dropped, not sent late: the host sees the seq gap */
        sei();
        uint8_t wire[AC_TELEMETRY_WIRE];
        uint8_t n = ac_fw_tick(&fw, t, l, r, fault ? AC_ST_ENCODER_FAULT : 0, wire);
        dac_update(fw.longitudinal_mv, fw.angular_mv, 1); /* every tick: also refreshes after glitches */
        uart_write(wire, n);
    }
    /* Sleep until the next interrupt unless work arrived meanwhile (sei+sleep is atomic). */
    cli();
    if (rx_tail == rx_head && !tick_pending && !watch_pending) {
        sleep_enable();
        sei();
        sleep_cpu();
        sleep_disable();
    }
    sei();
}
