"""The MuJoCo plant under the emulator (`--physics mujoco`): the model, the world, the camera."""
