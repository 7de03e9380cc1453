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

/* The logger's progress (the shim's item 4): a POSIX shared memory object of this name,
   with the logger's pid. `handled` counts the messages its handler has taken; `queued` the
   events it handed its writer thread (a bundle's parts each); `written` those the writer
   has written (lcm_eventlog_write_event returned). lcm-logger's writer, stopped by SIGINT,
   drops what it has not written yet: queued == written says nothing is pending. `magic` is
   SHOAL_LOGGER_PROGRESS_MAGIC once the counters run. */
#define SHOAL_LOGGER_PROGRESS_NAME "/shoal-logger-%ld"
#define SHOAL_LOGGER_PROGRESS_MAGIC 0x53484f414c50524bULL /* "SHOALPRK" */

/* A logger on another host (shoal run --hosts), whose /dev/shm the launcher cannot see,
   says instead that it has subscribed: with SHOAL_LOGGER_SAY_SUBSCRIBED=1 in its
   environment the shim writes this line to its standard error once it has. */
#define SHOAL_LOGGER_SAY_SUBSCRIBED_ENV "SHOAL_LOGGER_SAY_SUBSCRIBED"
#define SHOAL_LOGGER_SUBSCRIBED_LINE "shoal lcm queue shim: subscribed"

#include <stdint.h>

typedef struct {
    uint64_t magic;
    uint64_t handled;
    uint64_t queued;
    uint64_t written;
} ShoalLoggerProgress;

#endif
