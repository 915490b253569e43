/* main() for plain avr-gcc builds (Makefile); the Arduino IDE uses autochair_arduino.ino instead. */
#ifndef ARDUINO
#include "ac_board.h"

int main(void) {
    ac_app_setup();
    for (;;) ac_app_loop_once();
}
#endif
