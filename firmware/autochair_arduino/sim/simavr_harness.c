/* Run the real firmware ELF in simavr (ATmega328P, 16 MHz) in real time, with:
 *   - UART0 bridged to a pty (printed first: "PTY /dev/pts/N"), so the gateway can open it;
 *   - two quadrature encoders driven on A0..A3 at constant rates (--left-cps/--right-cps);
 *   - the MCP4922 decoded from SPI + /CS + /LDAC: "DAC <sim_us> <code_A> <code_B>" on change;
 *   - the relay pin: "RELAY <sim_us> <0|1>"; host silence: "HOSTIDLE <sim_us_of_last_rx_byte>".
 * Times are simulated µs (cycles / 16), so timing checks do not depend on host load.
 * Build: make harness. Run: build/simavr_harness build/autochair_arduino.elf [--left-cps N] ... */
#define _GNU_SOURCE
#include <errno.h>
#include <stdarg.h>
#include <fcntl.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_ioport.h>
#include <avr_spi.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_irq.h>

#define FREQ 16000000UL
#define US(avr) ((unsigned long long)(avr)->cycle / (FREQ / 1000000UL))

static volatile sig_atomic_t stop_flag;
static int pty_master = -1;
static int uart_xoff;
static unsigned long long last_rx_cycle, rx_bytes_since_idle;
static struct timespec wall0;
static avr_cycle_count_t cycle0;

/* --- UART <-> pty ------------------------------------------------------------------------- */
static void uart_out(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    uint8_t b = (uint8_t)value;
    if (write(pty_master, &b, 1) < 0) { /* nobody reading: drop, like a real unplugged cable */ }
}
static void uart_xon(struct avr_irq_t *irq, uint32_t v, void *p) { (void)irq; (void)v; (void)p; uart_xoff = 0; }
static void uart_xoff_cb(struct avr_irq_t *irq, uint32_t v, void *p) { (void)irq; (void)v; (void)p; uart_xoff = 1; }

static uint8_t rx_pending[512];
static int rx_len, rx_pos;

static avr_cycle_count_t pump_rx(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    if (rx_pos == rx_len) {
        rx_pos = 0;
        ssize_t n = read(pty_master, rx_pending, sizeof rx_pending);
        rx_len = n > 0 ? (int)n : 0;
    }
    avr_irq_t *in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    while (rx_pos < rx_len && !uart_xoff) {
        avr_raise_irq(in, rx_pending[rx_pos++]);
        last_rx_cycle = avr->cycle;
        rx_bytes_since_idle++;
    }
    if (rx_bytes_since_idle && avr->cycle - last_rx_cycle > FREQ / 20) { /* 50 ms silence */
        printf("HOSTIDLE %llu\n", last_rx_cycle / (FREQ / 1000000UL));
        fflush(stdout);
        rx_bytes_since_idle = 0;
    }
    return when + FREQ / 10000; /* every 100 µs */
}

/* --- real-time pacing: never run ahead of the wall clock ------------------------------------ */
static avr_cycle_count_t pace(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    double wall = (double)(now.tv_sec - wall0.tv_sec) + (double)(now.tv_nsec - wall0.tv_nsec) * 1e-9;
    double sim = (double)(avr->cycle - cycle0) / FREQ;
    if (sim > wall) {
        double d = sim - wall;
        struct timespec ts = {(time_t)d, (long)((d - (double)(time_t)d) * 1e9)};
        nanosleep(&ts, NULL);
    }
    return when + FREQ / 1000; /* every 1 ms */
}

static void no_sleep(avr_t *avr, avr_cycle_count_t howlong) { (void)avr; (void)howlong; }

/* --- encoders ------------------------------------------------------------------------------- */
typedef struct {
    int pin_a; /* port C pin of A; B is pin_a + 1 */
    long cps;  /* counts per second, signed */
    int phase;
} encoder_t;

static encoder_t encoders[2] = {{0, 0, 0}, {2, 0, 0}};
static const int GRAY[4] = {0, 1, 3, 2}; /* AB = A | B << 1; A leads B = forward = +1 */

static avr_cycle_count_t step_encoder(avr_t *avr, avr_cycle_count_t when, void *param) {
    encoder_t *e = param;
    e->phase = (e->phase + (e->cps > 0 ? 1 : 3)) & 3;
    int v = GRAY[e->phase];
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), e->pin_a), v & 1);
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), e->pin_a + 1), (v >> 1) & 1);
    return when + FREQ / (unsigned long)labs(e->cps);
}

/* --- MCP4922 on SPI (/CS = PB2, /LDAC = PB1) and the relay (PB0) ---------------------------- */
static uint8_t spi_bytes[2];
static int spi_count, cs_low;
static int dac_input[2] = {-1, -1}, dac_out[2] = {-1, -1};
static int relay = -1;
static avr_t *g_avr;

static void spi_out(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    if (cs_low && spi_count < 2) spi_bytes[spi_count] = (uint8_t)value;
    if (cs_low) spi_count++;
}

static void cs_change(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    if (!value) {
        cs_low = 1;
        spi_count = 0;
    } else if (cs_low) {
        cs_low = 0;
        if (spi_count == 2) {
            unsigned word = (unsigned)spi_bytes[0] << 8 | spi_bytes[1];
            if (word & 0x1000) dac_input[(word >> 15) & 1] = (int)(word & 0x0FFF); /* SHDN=1: active */
        }
    }
}

static void ldac_change(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    if (value) return; /* transfer on the falling edge */
    if (dac_input[0] != dac_out[0] || dac_input[1] != dac_out[1]) {
        dac_out[0] = dac_input[0];
        dac_out[1] = dac_input[1];
        printf("DAC %llu %d %d\n", US(g_avr), dac_out[0], dac_out[1]);
        fflush(stdout);
    }
}

static void relay_change(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    if ((int)value != relay) {
        relay = (int)value;
        printf("RELAY %llu %d\n", US(g_avr), relay);
        fflush(stdout);
    }
}

/* simavr's log goes to stderr: stdout carries only our event lines */
static void log_stderr(avr_t *avr, const int level, const char *fmt, va_list ap) {
    (void)avr;
    if (level <= LOG_WARNING) vfprintf(stderr, fmt, ap);
}

static void on_signal(int sig) { (void)sig; stop_flag = 1; }

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s firmware.elf [--left-cps N] [--right-cps N]\n", argv[0]);
        return 2;
    }
    for (int i = 2; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--left-cps")) encoders[0].cps = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--right-cps")) encoders[1].cps = atol(argv[i + 1]);
        else { fprintf(stderr, "unknown option %s\n", argv[i]); return 2; }
    }
    avr_global_logger_set(log_stderr);
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(argv[1], &fw) != 0) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 1;
    }
    avr_t *avr = avr_make_mcu_by_name("atmega328p");
    if (!avr) { fprintf(stderr, "simavr has no atmega328p\n"); return 1; }
    g_avr = avr;
    avr_init(avr);
    fw.frequency = FREQ;
    avr_load_firmware(avr, &fw);
    avr->frequency = FREQ;
    avr->sleep = no_sleep; /* we pace against the wall clock ourselves */

    int slave;
    char name[256];
    if (openpty(&pty_master, &slave, name, NULL, NULL) < 0) { perror("openpty"); return 1; }
    struct termios tio;
    tcgetattr(slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    /* keep `slave` open: the master then never sees EIO when the gateway closes and reopens */
    fcntl(pty_master, F_SETFL, fcntl(pty_master, F_GETFL) | O_NONBLOCK);

    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_out, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), uart_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), uart_xoff_cb, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_SPI_GETIRQ(0), SPI_IRQ_OUTPUT), spi_out, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 2), cs_change, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 1), ldac_change, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 0), relay_change, NULL);

    clock_gettime(CLOCK_MONOTONIC, &wall0);
    cycle0 = avr->cycle;
    avr_cycle_timer_register(avr, FREQ / 1000, pace, NULL);
    avr_cycle_timer_register(avr, FREQ / 10000, pump_rx, NULL);
    for (int i = 0; i < 2; i++)
        if (encoders[i].cps) avr_cycle_timer_register(avr, FREQ / 100, step_encoder, &encoders[i]);

    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);
    printf("PTY %s\n", name);
    fflush(stdout);
    int state = cpu_Running;
    while (!stop_flag && state != cpu_Done && state != cpu_Crashed) state = avr_run(avr);
    if (state == cpu_Crashed) { fprintf(stderr, "firmware crashed at pc 0x%x\n", avr->pc); return 1; }
    return 0;
}
