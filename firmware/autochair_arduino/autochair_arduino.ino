// autochair chair firmware: encoders in, joystick voltages out, COBS+CRC frames to the host.
// All code lives in the .c files beside this sketch (the IDE compiles them too), so the same
// sources build with plain avr-gcc (Makefile) and the protocol is unit-tested on the host.
// See README.md in this folder for wiring and the safety relay.
#include "ac_board.h"

void setup() { ac_app_setup(); }

void loop() { ac_app_loop_once(); }
