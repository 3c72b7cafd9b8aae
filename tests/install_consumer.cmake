message(FATAL_ERROR "placeholder")
