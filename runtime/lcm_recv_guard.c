/* LCM 1.3.1's UDP multicast receiver (lcm_udpm.c, Debian's liblcm) trusts the header of
   what it receives. A fragment whose fragment_offset lies near 2^32 passes its bounds
   check, computed in 32 bits, and memcpy then writes far outside the message's buffer; a
   short message whose channel name has no terminating NUL within the datagram gets a size
   that wraps below zero. One such datagram from any user of the host crashes the process
   that receives with LCM's own thread: lcm-logger (which would end the run) and
   `shoal analyze --live`. Shoal's own receiver (runtime/udpm_receiver.cc) checks every
   header itself.

   recvmsg, defined here, stands before the C library's for every caller of the process:
   in lcm-logger through the shim preloaded into it (runtime/lcm_queue_shim.c), in the
   shoal program because the dynamic linker binds liblcm's call to the definition of the
   executable. A datagram in LCM's format whose header does not add up is returned as an
   empty one, which LCM drops as too short to be its own; any other datagram, LCM's or
   not, is returned as it came. */
#define _GNU_SOURCE
#include "runtime/lcm_recv_guard.h"

#include <dlfcn.h>
#include <stdatomic.h>
#include <stdint.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

enum {
    kShortMagic = 0x4c433032, /* "LC02": a message in one datagram */
    kLongMagic = 0x4c433033,  /* "LC03": one fragment of a larger message */
    kShortHeader = 8,         /* magic, sequence number */
    kLongHeader = 20,         /* magic, sequence, size, offset, fragment number and count */
    kMaxChannel = 63          /* LCM_MAX_CHANNEL_NAME_LENGTH */
};

static atomic_ulong refused;

static uint32_t Be32(const unsigned char *p)
{
    return ((uint32_t) p[0] << 24) | ((uint32_t) p[1] << 16) | ((uint32_t) p[2] << 8) | p[3];
}

static uint32_t Be16(const unsigned char *p) { return ((uint32_t) p[0] << 8) | p[1]; }

/* The bytes of the channel name at p with its NUL, if it ends within n bytes and is no
   longer than LCM allows; else 0. */
static size_t ChannelBytes(const unsigned char *p, size_t n)
{
    const size_t limit = n < kMaxChannel + 1 ? n : kMaxChannel + 1;
    const unsigned char *nul = (const unsigned char *) memchr(p, 0, limit);
    return nul == NULL ? 0 : (size_t) (nul - p) + 1;
}

int shoal_lcm_datagram_ok(const unsigned char *p, size_t n)
{
    if (n < 4) return 1; /* too short for LCM, which drops it itself */
    const uint32_t magic = Be32(p);
    if (magic == kShortMagic) {
        return n >= kShortHeader && ChannelBytes(p + kShortHeader, n - kShortHeader) > 0;
    }
    if (magic != kLongMagic) return 1; /* not LCM's: LCM drops it itself */
    if (n < kLongHeader) return 0;
    const uint64_t size = Be32(p + 8);
    const uint64_t offset = Be32(p + 12);
    const uint32_t fragment = Be16(p + 16);
    const uint32_t fragments = Be16(p + 18);
    uint64_t payload = n - kLongHeader;
    if (fragments == 0 || fragment >= fragments) return 0;
    if (fragment == 0) { /* the first fragment carries the channel, at offset 0 */
        const size_t channel = ChannelBytes(p + kLongHeader, (size_t) payload);
        if (channel == 0 || offset != 0) return 0;
        payload -= channel;
    }
    return offset + payload <= size; /* 64 bits: no wrap */
}

unsigned long shoal_lcm_datagrams_refused(void) { return atomic_load(&refused); }

typedef ssize_t (*RecvmsgFn)(int, struct msghdr *, int);

static ssize_t RealRecvmsg(int fd, struct msghdr *msg, int flags)
{
    static _Atomic(RecvmsgFn) real = NULL;
    RecvmsgFn f = atomic_load(&real);
    if (f == NULL) {
        f = (RecvmsgFn) dlsym(RTLD_NEXT, "recvmsg");
        if (f == NULL) return syscall(SYS_recvmsg, fd, msg, flags);
        atomic_store(&real, f);
    }
    return f(fd, msg, flags);
}

ssize_t recvmsg(int fd, struct msghdr *msg, int flags)
{
    const ssize_t n = RealRecvmsg(fd, msg, flags);
    if (n > 0 && msg != NULL && msg->msg_iovlen >= 1 && msg->msg_iov != NULL &&
        msg->msg_iov[0].iov_len >= (size_t) n &&
        !shoal_lcm_datagram_ok((const unsigned char *) msg->msg_iov[0].iov_base, (size_t) n)) {
        atomic_fetch_add(&refused, 1);
        return 0;
    }
    return n;
}
