/* Build-time configuration of the firmware. Every value can be overridden with -D on the make
 * command line (see the Makefile and README.md), e.g. `make MICROSTEPS=8 STEPS_PER_REV=400`. */
#ifndef CONFIG_H
#define CONFIG_H

#ifndef F_CPU
#define F_CPU 16000000UL
#endif

/* Full steps of the motor per turntable revolution (include any gearing: a 200-step motor behind
 * a 3:1 belt is 600). */
#ifndef STEPS_PER_REV
#define STEPS_PER_REV 200
#endif
/* Microstepping set on the driver's MS pins (A4988: 1..16, DRV8825: 1..32). */
#ifndef MICROSTEPS
#define MICROSTEPS 16
#endif
#define USTEPS_PER_TURN ((int32_t)STEPS_PER_REV * (int32_t)MICROSTEPS)

/* The firmware's hard limits, reported in HELLO_REPLY; SET_LIMITS may only lower them. */
#ifndef MAX_SPEED_MDEG_S
#define MAX_SPEED_MDEG_S 90000UL
#endif
#ifndef MAX_ACCEL_MDEG_S2
#define MAX_ACCEL_MDEG_S2 180000UL
#endif
/* The range MOVE_ABS/MOVE_REL targets must lie in (millidegrees). */
#ifndef ANGLE_MIN_MDEG
#define ANGLE_MIN_MDEG (-3600000L)
#endif
#ifndef ANGLE_MAX_MDEG
#define ANGLE_MAX_MDEG 3600000L
#endif
/* Speed of the home search (one revolution at most). */
#ifndef HOME_SPEED_MDEG_S
#define HOME_SPEED_MDEG_S 20000UL
#endif

/* Stepper timer rate: one ISR per tick decides whether to step. At most one step per tick, so
 * the top speed must stay below TICK_HZ / 2 steps/s for an even pulse train. */
#ifndef TICK_HZ
#define TICK_HZ 10000UL
#endif

/* Light channels on timer-4 PWM pins (1..3 on this board). */
#ifndef LIGHT_CHANNELS
#define LIGHT_CHANNELS 3
#endif
/* PWM period in timer counts (12 bits: 3.9 kHz at 16 MHz, fast enough for ~1 ms exposures). */
#ifndef LIGHT_PWM_TOP
#define LIGHT_PWM_TOP 4095U
#endif
/* Time after switching a channel on before it reports `stable` (LED driver soft start). The
 * firmware has no warm-up sensor, so this is a fixed delay. */
#ifndef LIGHT_SETTLE_MS
#define LIGHT_SETTLE_MS 50U
#endif

#ifndef WATCHDOG_DEFAULT_MS
#define WATCHDOG_DEFAULT_MS 2000U
#endif

/* SIM_HOME=1 (the QEMU build): there is no switch, so the home search "finds" it after
 * SIM_HOME_MDEG of travel. Never set this for hardware. */
#ifndef SIM_HOME
#define SIM_HOME 0
#endif
#ifndef SIM_HOME_MDEG
#define SIM_HOME_MDEG 5000L
#endif

/* BOOT_DELAY_MS > 0 (test builds): after a reset the firmware reads and discards the UART for
 * this long before it answers, as the Mega's stk500v2 bootloader holds the UART for 1-2 s after
 * the reset that opening the USB port causes. The QEMU tests use it to check that the host waits
 * for such a board; a flashed board has the real bootloader and leaves this 0. */
#ifndef BOOT_DELAY_MS
#define BOOT_DELAY_MS 0
#endif

#ifndef FW_NAME
#if SIM_HOME
#define FW_NAME "brdf-mega-qemu"
#else
#define FW_NAME "brdf-mega"
#endif
#endif

#endif
