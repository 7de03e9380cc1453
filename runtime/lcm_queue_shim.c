/* Preloaded into the run's lcm-logger (LD_PRELOAD, set by shoal run). Eight things, all on
   lcm-logger's behalf, through the public API of LCM, GLib and the C library:

   1. Every subscription lcm-logger makes gets a queue of SHOAL_LOGGER_QUEUE_CAPACITY
      messages instead of LCM's 30. LCM's receive thread reads each datagram off the socket
      and queues it for the subscription until the program's handler thread takes it; beyond
      the queue's capacity it drops the message. lcm-logger 1.3.1 (Debian liblcm-bin) never
      sets the capacity and has no option for it, so a burst of more than 30 messages that
      arrives while its handler thread waits for the CPU -- the states of 64 vehicles
      stepping the same tick, in lockstep or in real time -- loses states from the log.
      Memory stays bounded: the queue holds what was received and not yet handed to the
      logger's writer, which itself drops beyond its --max-unwritten-mb.

   2. A recordable bundle (runtime/lcm_bus.h, bundle_wire: magic "SHB2" on SHOAL_BUNDLE,
      each part a message as it would go out alone, its authentication trailer included) is
      handed to lcm-logger's handler part by part, each on its own channel with the bundle's
      receive time, so that the log holds the messages as if each had been published alone:
      readers of the log never see the bundle. A process sends its states of a lockstep
      window as one such bundle: one datagram and one wake-up of the logger for many
      messages. Anything else (a malformed bundle too) is handed on as it came.

   3. The parts of one bundle reach lcm-logger's writer thread in one hand-off. Its handler
      queues each message for the writer (g_async_queue_push); handed a bundle's parts one by
      one, the writer on the other CPU wakes for the first, writes it, finds the queue empty
      and sleeps again before the next is pushed: a wake-up per part, most of the logger's
      CPU at scale (docs/benchmarks.md). While a bundle is unpacked the shim holds the
      queue's lock and pushes each part under it (g_async_queue_push_unlocked), so the
      writer wakes once and finds them all. No deadlock: the writer takes the queue's lock
      and lcm-logger's own mutex one after the other, never one inside the other, and the
      handler takes that mutex under the queue's lock, as it takes nothing else.

   4. With SHOAL_LOGGER_PROGRESS=1 in its environment, the logger publishes, once it has
      subscribed, how many messages (datagrams, a bundle counting once) its handler has
      taken off LCM's queue, in a shared memory object named after its pid
      (SHOAL_LOGGER_PROGRESS_NAME); with SHOAL_LOGGER_SAY_SUBSCRIBED=1 (a logger on another
      host, whose /dev/shm the launcher cannot see) it says on its standard error that it
      has subscribed. The launcher starts the run's processes only then. The lockstep
      clock master, whose messages are all the logger hears on a run with an uplink, then
      knows how far behind the logger is, and lets it fall behind by a window instead of
      waiting at every window until it is idle (channel_emulator/recorder_gate.h). It also
      counts the events handed to the writer thread and those written, so that at the end
      the clock master waits until nothing is pending: lcm-logger's writer, stopped by
      SIGINT, drops what it has not written yet.

   5. lcm-logger's memory is locked (mlockall, current and future) at its first
      subscription, when permitted (root, or a large enough RLIMIT_MEMLOCK): its resident
      size is then what it has allocated, not the pages of LCM's receive ring and of its
      heaps that a backlog on a loaded machine happens to reach first, which a soak's memory
      verdict would read as growth; and the logger takes no page fault mid-run.

   6. With SHOAL_LOGGER_BATCH=1 in its environment (shoal run sets it in lockstep), the
      logger runs under SCHED_BATCH, set before main() so that every thread it starts
      inherits it. Its nice value is kept, so it gets the same share of the CPU; what
      changes is that a woken logger thread no longer preempts the process running on its
      CPU. In lockstep that process is often the clock master finishing a window, the
      critical path of the run: the logger's three threads woken per datagram preempted it
      several times a window (docs/benchmarks.md).

   7. lcm-logger allocates each message it queues for its writer and frees it once
      written, so its heaps are as large as the largest backlog so far. A lockstep window's
      record reaches it at once (the states of a window of up to 50 ticks), and a later
      phase of a soak with longer delays has longer windows: its heaps grew by a quarter of
      a megabyte there, which the soak's memory verdict (1 %) read as a leak. Each heap
      therefore grows by 4 MB more than it needs whenever it grows, and is never trimmed:
      the first window takes the memory a run's windows need (and item 5 locks it).

   8. LCM's receive thread is guarded against datagrams whose header would make it write
      outside its buffers (runtime/lcm_recv_guard.c, linked into this library): one forged
      fragment would otherwise crash the logger and end the run. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <malloc.h>
#include <sched.h>
#include <sys/mman.h>
#include <unistd.h>

#include "runtime/lcm_queue_shim.h"
#include "runtime/lcm_recv_guard.h"

/* Item 8: what the receive guard refused is said in the logger's output, at its exit. */
__attribute__((destructor)) static void SayRefused(void)
{
    const unsigned long n = shoal_lcm_datagrams_refused();
    if (n > 0) {
        fprintf(stderr, "shoal lcm queue shim: %lu malformed LCM datagram(s) refused\n", n);
    }
}

/* Item 7. */
__attribute__((constructor)) static void SteadyHeap(void)
{
    mallopt(M_TOP_PAD, 4 << 20);
    mallopt(M_TRIM_THRESHOLD, 64 << 20);
}

/* Item 6. */
__attribute__((constructor)) static void BatchScheduling(void)
{
    const char *on = getenv("SHOAL_LOGGER_BATCH");
    if (on == NULL || strcmp(on, "1") != 0) return;
    struct sched_param sp;
    memset(&sp, 0, sizeof(sp));
    if (sched_setscheduler(0, SCHED_BATCH, &sp) != 0) {
        fprintf(stderr, "shoal lcm queue shim: not SCHED_BATCH (%s)\n", strerror(errno));
    }
}

/* Item 4: the counter the handler thread advances, or NULL. */
static ShoalLoggerProgress *progress;

static void ShareProgress(void)
{
    const char *on = getenv("SHOAL_LOGGER_PROGRESS");
    if (on == NULL || strcmp(on, "1") != 0) return;
    char name[64];
    snprintf(name, sizeof(name), SHOAL_LOGGER_PROGRESS_NAME, (long) getpid());
    /* A pid is not reused while its process lives, so an object of this name is an
       earlier process's leftover: start it anew. */
    shm_unlink(name);
    const int fd = shm_open(name, O_RDWR | O_CREAT | O_EXCL, 0600);
    if (fd < 0 || ftruncate(fd, sizeof(ShoalLoggerProgress)) != 0) {
        fprintf(stderr, "shoal lcm queue shim: no progress counter (%s: %s)\n", name,
                strerror(errno));
        if (fd >= 0) close(fd);
        return;
    }
    void *m = mmap(NULL, sizeof(ShoalLoggerProgress), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    close(fd);
    if (m == MAP_FAILED) return;
    progress = (ShoalLoggerProgress *) m;
    __atomic_store_n(&progress->handled, 0, __ATOMIC_RELAXED);
    __atomic_store_n(&progress->queued, 0, __ATOMIC_RELAXED);
    __atomic_store_n(&progress->written, 0, __ATOMIC_RELAXED);
    __atomic_store_n(&progress->magic, SHOAL_LOGGER_PROGRESS_MAGIC, __ATOMIC_RELEASE);
}

static void Advance(void)
{
    if (progress != NULL) __atomic_add_fetch(&progress->handled, 1, __ATOMIC_RELEASE);
}

static void Count(uint64_t *counter)
{
    if (progress != NULL) __atomic_add_fetch(counter, 1, __ATOMIC_RELEASE);
}

typedef int (*WriteEventFn)(lcm_eventlog_t *, lcm_eventlog_event_t *);

/* lcm-logger's writer thread writes each event through liblcm: counted once written. */
int lcm_eventlog_write_event(lcm_eventlog_t *log, lcm_eventlog_event_t *event)
{
    static WriteEventFn real = NULL;
    if (real == NULL) real = (WriteEventFn) dlsym(RTLD_NEXT, "lcm_eventlog_write_event");
    if (real == NULL) return -1;
    const int status = real(log, event);
    if (progress != NULL) Count(&progress->written);
    return status;
}

typedef lcm_subscription_t *(*SubscribeFn)(lcm_t *, const char *, lcm_msg_handler_t, void *);

/* GLib's asynchronous queue, as lcm-logger uses it; looked up at run time, so that the shim
   needs no GLib headers or link of its own. */
typedef struct _GAsyncQueue GAsyncQueue;
typedef void (*QueueFn)(GAsyncQueue *);
typedef void (*PushFn)(GAsyncQueue *, void *);
static PushFn real_push, push_unlocked;
static QueueFn queue_lock, queue_unlock;
/* While a bundle is unpacked (the handler thread): the queue whose lock is held, if any. */
static __thread int unbundling;
static __thread GAsyncQueue *held;

static int FindQueueFunctions(void)
{
    if (real_push == NULL) {
        real_push = (PushFn) dlsym(RTLD_NEXT, "g_async_queue_push");
        push_unlocked = (PushFn) dlsym(RTLD_DEFAULT, "g_async_queue_push_unlocked");
        queue_lock = (QueueFn) dlsym(RTLD_DEFAULT, "g_async_queue_lock");
        queue_unlock = (QueueFn) dlsym(RTLD_DEFAULT, "g_async_queue_unlock");
    }
    return real_push != NULL && push_unlocked != NULL && queue_lock != NULL &&
           queue_unlock != NULL;
}

void g_async_queue_push(GAsyncQueue *queue, void *data)
{
    if (progress != NULL) Count(&progress->queued);
    if (!FindQueueFunctions()) {
        if (real_push != NULL) real_push(queue, data);
        return;
    }
    if (!unbundling) {
        real_push(queue, data);
        return;
    }
    if (held != queue) {
        if (held != NULL) queue_unlock(held);
        queue_lock(queue);
        held = queue;
    }
    push_unlocked(queue, data);
}

/* lcm-logger's own handler and its argument, for one subscription. */
typedef struct {
    lcm_msg_handler_t handler;
    void *user;
} Target;

static const char kBundleChannel[] = "SHOAL_BUNDLE";
static const unsigned char kRecordable[4] = {'S', 'H', 'B', '2'};
enum { kMaxChannel = 63 };

/* Whether a bundle's part names one of the run's channels (SHOAL_ and capitals, digits,
   underscores, hyphens: SHOAL_HEALTH_-1 is the channel emulator's), as the logger's own
   --channel filter would have let through: a forged bundle must not write other names into
   the log, which readers would take for damage. */
static int RunChannel(const unsigned char *name, uint32_t len)
{
    static const char kPrefix[] = "SHOAL_";
    if (len < sizeof(kPrefix) - 1 || memcmp(name, kPrefix, sizeof(kPrefix) - 1) != 0) return 0;
    for (uint32_t k = sizeof(kPrefix) - 1; k < len; ++k) {
        const unsigned char c = name[k];
        if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) {
            return 0;
        }
    }
    return 1;
}

/* Walks the parts of a recordable bundle: with `t` NULL only checks that it is well formed
   (a bundle is handed on entire or not at all); else hands each part to t's handler. */
static int ForEachPart(const lcm_recv_buf_t *rbuf, const Target *t)
{
    const unsigned char *p = (const unsigned char *) rbuf->data;
    const uint32_t size = rbuf->data_size;
    uint32_t pos = sizeof(kRecordable);
    while (pos < size) {
        const uint32_t len = p[pos];
        if (len < 1 || len > kMaxChannel || size - pos - 1 < len + 4) return 0;
        if (!RunChannel(p + pos + 1, len)) return 0;
        if (len == sizeof(kBundleChannel) - 1 && memcmp(p + pos + 1, kBundleChannel, len) == 0) {
            return 0; /* never a bundle inside a bundle */
        }
        const unsigned char *n = p + pos + 1 + len;
        const uint32_t bytes =
            ((uint32_t) n[0] << 24) | ((uint32_t) n[1] << 16) | ((uint32_t) n[2] << 8) | n[3];
        if (bytes > size - pos - 1 - len - 4) return 0;
        if (t != NULL) {
            char channel[kMaxChannel + 1];
            memcpy(channel, p + pos + 1, len);
            channel[len] = '\0';
            lcm_recv_buf_t part = *rbuf;
            part.data = (void *) (n + 4);
            part.data_size = bytes;
            t->handler(&part, channel, t->user);
        }
        pos += 1 + len + 4 + bytes;
    }
    return 1;
}

static void Unbundle(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    const Target *t = (const Target *) user;
    if (strcmp(channel, kBundleChannel) == 0 && rbuf->data_size >= sizeof(kRecordable) &&
        memcmp(rbuf->data, kRecordable, sizeof(kRecordable)) == 0 && ForEachPart(rbuf, NULL)) {
        unbundling = 1;
        ForEachPart(rbuf, t);
        unbundling = 0;
        if (held != NULL) {
            queue_unlock(held);
            held = NULL;
        }
        Advance();
        return;
    }
    t->handler(rbuf, channel, t->user);
    /* Every LCM instance greets its group once (LCM_SELF_TEST) as it starts, the clock
       master's too: not one of the messages it counts as sent. */
    if (strcmp(channel, "LCM_SELF_TEST") != 0) Advance();
}

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
    /* Lives as long as the subscription: lcm-logger subscribes once, for the whole run. */
    Target *t = (Target *) malloc(sizeof(Target));
    if (t == NULL) return real(lcm, channel, handler, userdata);
    t->handler = handler;
    t->user = userdata;
    /* The first subscription to a UDP multicast bus joins the group and then runs LCM's
       self test, which subscribes to LCM_SELF_TEST from inside this call and, until its
       own message comes back, discards every other message received. The logger has
       subscribed, for what the run sends, only once the outermost call returns. */
    static __thread int depth = 0;
    ++depth;
    lcm_subscription_t *s = real(lcm, channel, Unbundle, t);
    --depth;
    if (s == NULL) {
        free(t);
        return NULL;
    }
    if (lcm_subscription_set_queue_capacity(s, SHOAL_LOGGER_QUEUE_CAPACITY) != 0) {
        fprintf(stderr, "shoal lcm queue shim: cannot set the queue capacity of \"%s\"\n",
                channel);
    }
    /* Said last: once the count's name exists (or the line is out) the run starts, and
       until this call returns nothing takes messages off the queue, which must by then
       hold a burst, and mlockall takes tens of milliseconds. */
    static int locked = 0;
    if (!locked && depth == 0) {
        locked = 1;
        if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
            fprintf(stderr, "shoal lcm queue shim: memory not locked (mlockall: %s)\n",
                    strerror(errno));
        }
        ShareProgress();
        const char *say = getenv(SHOAL_LOGGER_SAY_SUBSCRIBED_ENV);
        if (say != NULL && strcmp(say, "1") == 0) {
            fprintf(stderr, "%s\n", SHOAL_LOGGER_SUBSCRIBED_LINE);
            fflush(stderr);
        }
    }
    return s;
}
