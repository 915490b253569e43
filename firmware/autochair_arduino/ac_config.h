/* Build-time settings; override with -D (Makefile: make CFLAGS_EXTRA=-DAC_BAUD=250000). */
#ifndef AC_CONFIG_H
#define AC_CONFIG_H

#ifndef F_CPU
#define F_CPU 16000000UL
#endif
#ifndef AC_BAUD
#define AC_BAUD 115200UL /* 20 B telemetry + 14 B command at 100 Hz = 3400 B/s of 11520 B/s */
#endif
#ifndef AC_FRAME_US
#define AC_FRAME_US 10000UL /* telemetry period: 100 Hz (keys.DRIVE_RATE_HZ; <= 32768) */
#endif
#ifndef AC_DAC_VREF_MV
#define AC_DAC_VREF_MV 4096UL /* MCP4922 VREFA/VREFB from a 4.096 V reference: 1 code = 1 mV */
#endif
#ifndef AC_LEFT_INVERT
#define AC_LEFT_INVERT 0 /* 1 flips a wheel's count direction (+ must be forward) */
#endif
#ifndef AC_RIGHT_INVERT
#define AC_RIGHT_INVERT 0
#endif

#endif
