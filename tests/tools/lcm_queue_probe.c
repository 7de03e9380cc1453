/* Subscribes to "PROBE" on the LCM URL given, publishes a burst of N messages to itself
   without handling any, waits until LCM's receive thread has read them all, then handles
   what its subscription queue kept and prints that count. With LCM's default queue it
   prints about 30; preloaded with runtime/lcm_queue_shim.c (as shoal run starts
   lcm-logger), N. Usage: lcm_queue_probe URL N */
#include <lcm/lcm.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static int handled = 0;

static void OnMessage(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    (void) rb;
    (void) channel;
    (void) user;
    ++handled;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: lcm_queue_probe URL N\n");
        return 2;
    }
    const int n = atoi(argv[2]);
    lcm_t *lcm = lcm_create(argv[1]);
    if (lcm == NULL || lcm_subscribe(lcm, "PROBE", OnMessage, NULL) == NULL) return 2;
    char payload[64] = {0};
    for (int k = 0; k < n; ++k) {
        if (lcm_publish(lcm, "PROBE", payload, sizeof(payload)) != 0) return 2;
        if (k % 20 == 19) {  /* paced: the kernel's socket buffer is not what is measured */
            const struct timespec pause = {0, 1000000};
            nanosleep(&pause, NULL);
        }
    }
    const struct timespec settle = {0, 300000000};
    nanosleep(&settle, NULL);
    while (lcm_handle_timeout(lcm, 0) > 0) {
    }
    printf("%d\n", handled);
    lcm_destroy(lcm);
    return 0;
}
