"""Action pages: the ROBOTIS binary file, the project's text format, the library, the player."""
