/* Preloaded into a run's processes by a test: lcm-logger subscribes SHOAL_TEST_SUBSCRIBE_DELAY_MS
   later than it would (after it has created its log), as a logger slow to start does on a
   loaded machine. Every other process is left as it is. */
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
        delay != NULL) {
        usleep((useconds_t) atoi(delay) * 1000);
    }
    return real == NULL ? NULL : real(lcm, channel, handler, user);
}
