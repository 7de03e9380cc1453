/* The subscription queue the run's lcm-logger gets from runtime/lcm_queue_shim.c
   (messages received and not yet handled). Plain C: the shim is C, the launcher and the
   channel emulator are C++. */
#ifndef SHOAL_RUNTIME_LCM_QUEUE_SHIM_H_
#define SHOAL_RUNTIME_LCM_QUEUE_SHIM_H_

#define SHOAL_LOGGER_QUEUE_CAPACITY 8192
/* LCM's own default, what lcm-logger 1.3.1 has without the shim (it has no option). */
#define SHOAL_LCM_DEFAULT_QUEUE_CAPACITY 30
/* The shim's file name, built next to the runtime library (build/runtime/). */
#define SHOAL_LCM_QUEUE_SHIM_FILE "libshoal_lcm_queue.so"

#endif
