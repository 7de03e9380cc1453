/* Preloaded into the run's lcm-logger (LD_PRELOAD, set by shoal run): every subscription
   lcm-logger makes gets a queue of SHOAL_LOGGER_QUEUE_CAPACITY messages instead of LCM's 30.

   Why: LCM's receive thread reads each datagram off the socket and queues it for the
   subscription until the program's handler thread takes it; beyond the queue's capacity it
   drops the message. lcm-logger 1.3.1 (Debian liblcm-bin) never sets the capacity and has
   no option for it, so a burst of more than 30 messages that arrives while its handler
   thread waits for the CPU -- the states of 64 vehicles stepping the same tick, in lockstep
   or in real time -- loses states from the log. lcm_subscription_set_queue_capacity is
   LCM's public API for exactly this; the shim only calls it on lcm-logger's behalf.
   Memory stays bounded: the queue holds what was received and not yet handed to the
   logger's writer, which itself drops beyond its --max-unwritten-mb. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <lcm/lcm.h>
#include <stdio.h>

#include "runtime/lcm_queue_shim.h"

typedef lcm_subscription_t *(*SubscribeFn)(lcm_t *, const char *, lcm_msg_handler_t, void *);

lcm_subscription_t *lcm_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler,
                                  void *userdata)
{
    static SubscribeFn real = NULL;
    if (real == NULL) {
        real = (SubscribeFn) dlsym(RTLD_NEXT, "lcm_subscribe");
        if (real == NULL) {
            fprintf(stderr, "shoal lcm queue shim: lcm_subscribe not found (%s)\n", dlerror());
            return NULL;
        }
    }
    lcm_subscription_t *s = real(lcm, channel, handler, userdata);
    if (s != NULL && lcm_subscription_set_queue_capacity(s, SHOAL_LOGGER_QUEUE_CAPACITY) != 0) {
        fprintf(stderr, "shoal lcm queue shim: cannot set the queue capacity of \"%s\"\n",
                channel);
    }
    return s;
}
