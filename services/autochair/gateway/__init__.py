"""Gateway: owns the serial link to the Arduino (encoders in, joystick voltages out)."""
