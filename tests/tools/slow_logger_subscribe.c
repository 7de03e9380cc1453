/* Preloaded into a run's processes by a test: lcm-logger subscribes SHOAL_TEST_SUBSCRIBE_DELAY_MS
   later than it would (after it has created its log), as a logger slow to start does on a
   loaded machine; 1500 ms without that variable (a logger on another host, started through
   ssh, gets its LD_PRELOAD through env(1) but not the test's other variables; none when
   only SHOAL_TEST_WRITE_DELAY_US, below, is set). Every other process is left as it is. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef void *(*SubscribeFn)(void *, const char *, void *, void *);

void *lcm_subscribe(void *lcm, const char *channel, void *handler, void *user)
{
    SubscribeFn real = (SubscribeFn) dlsym(RTLD_NEXT, "lcm_subscribe");
    char exe[256] = {0};
    const char *delay = getenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS");
    if (readlink("/proc/self/exe", exe, sizeof(exe) - 1) > 0 && strstr(exe, "lcm-logger") &&
        (delay != NULL || getenv("SHOAL_TEST_WRITE_DELAY_US") == NULL)) {
        usleep((useconds_t) (delay != NULL ? atoi(delay) : 1500) * 1000);
    }
    return real == NULL ? NULL : real(lcm, channel, handler, user);
}

/* With SHOAL_TEST_WRITE_DELAY_US, lcm-logger's writer takes that long more over each event,
   as a slow disk makes it: a backlog of messages received and not yet written builds up. */
typedef int (*WriteEventFn)(void *, void *);

int lcm_eventlog_write_event(void *log, void *event)
{
    WriteEventFn real = (WriteEventFn) dlsym(RTLD_NEXT, "lcm_eventlog_write_event");
    const char *delay = getenv("SHOAL_TEST_WRITE_DELAY_US");
    if (delay != NULL) usleep((useconds_t) atoi(delay));
    return real == NULL ? -1 : real(log, event);
}
