/* Stepper turntable on an A4988/DRV8825-class driver (STEP/DIR/ENABLE), trapezoidal speed
 * profile generated in the timer-1 interrupt, and the home search.
 *
 * Units at this interface: millidegrees (angles), millidegrees/s and /s^2 (limits). Inside:
 * microsteps, and speeds as fractions of a step per tick in 0.32 fixed point. */
#ifndef STEPPER_H
#define STEPPER_H

#include <stdint.h>

enum home_result { HOME_NONE, HOME_FOUND, HOME_FAILED };

void stepper_init(void);
/* Speed and acceleration limits (checked against the hard limits by the caller); they apply from
 * the next motion on. */
void stepper_set_limits(uint32_t speed_mdeg_s, uint32_t accel_mdeg_s2);
/* Starts a move to an absolute angle; the caller checked that the turntable is at rest. */
void stepper_move_to(int32_t angle_mdeg);
/* Starts the home search: at most one revolution at the home speed until the switch closes. */
void stepper_home(void);
/* Decelerates to rest (aborting a home search). */
void stepper_stop(void);
/* Reports, once, how a home search ended. */
enum home_result stepper_take_home_result(void);

uint8_t stepper_moving(void);
uint8_t stepper_enabled(void);
int32_t stepper_angle_mdeg(void);
int32_t stepper_target_mdeg(void);

#endif
