"""Motion modules. They see joint states in and produce goals out; they never import the bus
or Zenoh, so the same code runs on the emulator, the robot or a unit test."""
