/* Trapezoidal profile without multiplications in the interrupt: every tick the speed changes by
 * the acceleration, and `ramp` counts the steps taken while speeding up. Deceleration mirrors
 * acceleration tick for tick, so the distance needed to stop equals `ramp`: the ISR starts braking
 * once the steps left reach it. */
#include "stepper.h"

#include "board.h"
#include "config.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>
#include <util/delay.h>

/* Top speed must leave at least two ticks per step. */
#define MAX_STEPS_S ((uint64_t)MAX_SPEED_MDEG_S * USTEPS_PER_TURN / 360000UL)
_Static_assert(MAX_STEPS_S * 2 <= TICK_HZ,
               "MAX_SPEED_MDEG_S needs more than TICK_HZ / 2 steps per second; raise TICK_HZ");

/* Shared with the ISR. */
static volatile int32_t pos;        /* microsteps from home */
static volatile int32_t goal;       /* microsteps */
static volatile int8_t dir;         /* +1 / -1 while running */
static volatile uint8_t running;
/* Home search phases. When HOME starts on a closed switch, the turntable first backs off until
 * it opens, so home is always approached from the same side (repeatable to a step). */
enum { HOMING_OFF = 0, HOMING_SEARCH, HOMING_BACKOFF };
static volatile uint8_t homing;
static volatile uint32_t speed;     /* steps per tick, 0.32 fixed point */
static volatile uint32_t vmax;      /* idem */
static volatile uint32_t vmin;      /* start / final approach speed */
static volatile uint32_t accel;     /* speed change per tick, 0.32 fixed point */
static volatile uint32_t phase;
static volatile int32_t ramp;       /* steps taken while accelerating */
static volatile uint8_t home_result;
#if SIM_HOME
static volatile int32_t sim_travel;
#endif

/* Main-loop state. */
static int32_t target_mdeg;
static uint8_t enabled;
static uint32_t limit_speed_mdeg_s = MAX_SPEED_MDEG_S;
static uint32_t limit_accel_mdeg_s2 = MAX_ACCEL_MDEG_S2;

static int32_t mdeg_to_steps(int32_t mdeg)
{
    int64_t num = (int64_t)mdeg * USTEPS_PER_TURN;
    return (int32_t)(num >= 0 ? (num + 180000) / 360000 : (num - 180000) / 360000);
}

static int32_t steps_to_mdeg(int32_t steps)
{
    int64_t num = (int64_t)steps * 360000;
    int64_t half = USTEPS_PER_TURN / 2;
    return (int32_t)(num >= 0 ? (num + half) / USTEPS_PER_TURN : (num - half) / USTEPS_PER_TURN);
}

/* Steps per tick in 0.32 fixed point for mdeg/s; at least 1. */
static uint32_t speed_q32(uint32_t mdeg_s)
{
    uint64_t q = ((uint64_t)mdeg_s * USTEPS_PER_TURN << 16) / 360000UL * 65536UL / TICK_HZ;
    return q ? (uint32_t)q : 1;
}

static uint32_t accel_q32(uint32_t mdeg_s2)
{
    uint64_t q = ((uint64_t)mdeg_s2 * USTEPS_PER_TURN << 16) / 360000UL * 65536UL / TICK_HZ / TICK_HZ;
    return q ? (uint32_t)q : 1;
}

static uint32_t isqrt32(uint32_t x)
{
    uint32_t r = 0;
    for (uint32_t bit = 1UL << 30; bit; bit >>= 2) {
        if (x >= r + bit) {
            x -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
    }
    return r;
}

/* Start and final-approach speed: the speed one step of constant acceleration from rest reaches,
 * sqrt(2 a) steps/s, so the ramp begins without a slow first step and ends without crawling. */
static uint32_t start_speed_mdeg_s(uint32_t accel_mdeg_s2)
{
    uint32_t a_steps = (uint32_t)((uint64_t)accel_mdeg_s2 * USTEPS_PER_TURN / 360000UL);
    uint32_t v_steps = isqrt32(2 * a_steps);
    if (v_steps < 1) {
        v_steps = 1;
    }
    return (uint32_t)((uint64_t)v_steps * 360000UL / USTEPS_PER_TURN);
}

static uint8_t home_switch_closed(void)
{
#if SIM_HOME
    return sim_travel >= (int32_t)((int64_t)SIM_HOME_MDEG * USTEPS_PER_TURN / 360000);
#else
    return !(STEPPER_PIN & _BV(HOME_BIT)); /* closed to GND, pulled up when open */
#endif
}

ISR(TIMER1_COMPA_vect)
{
    if (!running) {
        return;
    }
    if (homing == HOMING_SEARCH && home_switch_closed()) {
        /* Home speed is below the motor's pull-in rate: stopping dead loses no step. */
        running = 0;
        homing = HOMING_OFF;
        speed = 0;
        ramp = 0;
        pos = 0;
        goal = 0;
        home_result = HOME_FOUND;
        return;
    }
    if (homing == HOMING_BACKOFF && !home_switch_closed()) {
        /* Off the switch: now search towards it (the main loop sees HOME_NONE meanwhile). */
        goal = pos + USTEPS_PER_TURN;
        dir = 1;
        STEPPER_PORT |= _BV(DIR_BIT);
        speed = vmin;
        phase = 0;
        homing = HOMING_SEARCH;
        return;
    }
    int32_t left = (goal - pos) * dir;
    uint32_t v = speed;
    uint8_t speeding_up = 0;
    if (left <= ramp) {
        v = (v > vmin + accel) ? v - accel : vmin;
    } else if (v < vmax) {
        v = (vmax - v > accel) ? v + accel : vmax;
        speeding_up = 1;
    } else if (v > vmax) {
        /* Defensive: limits change only between motions (stepper_set_limits). */
        v = (v - vmax > accel) ? v - accel : vmax;
    }
    speed = v;
    uint32_t before = phase;
    phase = before + v;
    if (phase >= before) {
        return; /* no whole step this tick */
    }
    STEPPER_PORT |= _BV(STEP_BIT);
    _delay_us(2); /* A4988 needs 1 us high, DRV8825 1.9 us */
    STEPPER_PORT &= (uint8_t)~_BV(STEP_BIT);
    pos += dir;
#if SIM_HOME
    if (homing) {
        sim_travel++;
    }
#endif
    if (speeding_up) {
        ramp++;
    } else if (left <= ramp && ramp > 0) {
        ramp--;
    }
    if (pos == goal) {
        running = 0;
        speed = 0;
        ramp = 0;
        phase = 0;
        if (homing) {
            /* A whole turn without the switch closing, or a backoff that never opened it. */
            homing = HOMING_OFF;
            home_result = HOME_FAILED;
        }
    }
}

void stepper_init(void)
{
    STEPPER_DDR |= _BV(STEP_BIT) | _BV(DIR_BIT) | _BV(ENABLE_BIT);
    STEPPER_PORT |= _BV(ENABLE_BIT); /* disabled until the first motion */
    STEPPER_DDR &= (uint8_t)~_BV(HOME_BIT);
    STEPPER_PORT |= _BV(HOME_BIT); /* pull-up */
    /* Timer 1, CTC on OCR1A, prescaler 8: 2 MHz counts. */
    TCCR1A = 0;
    TCCR1B = _BV(WGM12) | _BV(CS11);
    OCR1A = (uint16_t)(F_CPU / 8UL / TICK_HZ - 1UL);
    TIMSK1 = _BV(OCIE1A);
}

/* Limits apply from the next motion on: changing the acceleration mid-move would make `ramp`
 * (steps climbed at the old rate) a wrong stopping distance. */
void stepper_set_limits(uint32_t speed_mdeg_s, uint32_t accel_mdeg_s2)
{
    limit_speed_mdeg_s = speed_mdeg_s;
    limit_accel_mdeg_s2 = accel_mdeg_s2;
}

/* Loads the speed profile of a motion; only called while at rest. */
static void load_profile(uint32_t speed_mdeg_s, uint8_t constant_speed)
{
    uint32_t v = speed_q32(speed_mdeg_s);
    uint32_t a = accel_q32(limit_accel_mdeg_s2);
    uint32_t v0 = constant_speed ? v : speed_q32(start_speed_mdeg_s(limit_accel_mdeg_s2));
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        vmax = v;
        accel = a;
        vmin = v0 < v ? v0 : v;
    }
}

static void start(int32_t goal_steps, uint8_t homing_phase)
{
    STEPPER_PORT &= (uint8_t)~_BV(ENABLE_BIT);
    enabled = 1;
    int32_t from;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { from = pos; }
    if (goal_steps == from) {
        return;
    }
    int8_t d = goal_steps > from ? 1 : -1;
    if (d > 0) {
        STEPPER_PORT |= _BV(DIR_BIT);
    } else {
        STEPPER_PORT &= (uint8_t)~_BV(DIR_BIT);
    }
    _delay_us(1); /* DIR setup time before the first STEP edge */
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        goal = goal_steps;
        dir = d;
        speed = vmin;
        phase = 0;
        ramp = 0;
        homing = homing_phase;
        running = 1;
    }
}

void stepper_move_to(int32_t angle_mdeg)
{
    target_mdeg = angle_mdeg;
    load_profile(limit_speed_mdeg_s, 0);
    start(mdeg_to_steps(angle_mdeg), HOMING_OFF);
}

void stepper_home(void)
{
    uint32_t home = HOME_SPEED_MDEG_S < limit_speed_mdeg_s ? HOME_SPEED_MDEG_S : limit_speed_mdeg_s;
    /* Constant speed, below pull-in: the search may stop dead on the switch. */
    load_profile(home, 1);
    int32_t from;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        home_result = HOME_NONE;
        from = pos;
    }
#if SIM_HOME
    sim_travel = 0;
#endif
    target_mdeg = 0;
    if (home_switch_closed()) {
        start(from - USTEPS_PER_TURN / 8, HOMING_BACKOFF);
    } else {
        start(from + USTEPS_PER_TURN, HOMING_SEARCH);
    }
}

void stepper_stop(void)
{
    uint8_t was_running;
    int32_t g;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        was_running = running;
        if (running) {
            /* Brake now: the stopping distance is the ramp already climbed (never beyond the
             * goal already set). */
            if ((goal - pos) * dir > ramp + 1) {
                goal = pos + dir * (ramp + 1);
            }
            homing = HOMING_OFF; /* an aborted search is no failure: simply not homed */
        }
        g = goal;
    }
    if (was_running) {
        target_mdeg = steps_to_mdeg(g);
    }
}

enum home_result stepper_take_home_result(void)
{
    enum home_result r;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        r = (enum home_result)home_result;
        home_result = HOME_NONE;
    }
    if (r != HOME_NONE) {
        target_mdeg = 0;
        if (r == HOME_FAILED) {
            ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { target_mdeg = steps_to_mdeg(pos); }
        }
    }
    return r;
}

uint8_t stepper_moving(void) { return running; }

uint8_t stepper_enabled(void) { return enabled; }

/* At rest on the step nearest the target, the angle is the target: the host asked for that
 * angle and the turntable is there to the motor's resolution (PROTOCOL.md does not say how a
 * firmware with coarser steps than a millidegree reports arrival; the host driver takes
 * |angle - target| <= 1 as arrived). Anywhere else, the step position in millidegrees. */
int32_t stepper_angle_mdeg(void)
{
    int32_t p;
    uint8_t r;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        p = pos;
        r = running;
    }
    if (!r && p == mdeg_to_steps(target_mdeg)) {
        return target_mdeg;
    }
    return steps_to_mdeg(p);
}

int32_t stepper_target_mdeg(void) { return target_mdeg; }
