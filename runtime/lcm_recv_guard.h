/* The check of LCM datagrams that stands before LCM 1.3.1's receive thread
   (runtime/lcm_recv_guard.c): linked into the shoal program and into the shim preloaded
   into lcm-logger. */
#pragma once

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Whether LCM 1.3.1 may safely take the datagram p[0..n): 0 for a datagram in LCM's format
   (magic "LC02" or "LC03") whose header does not add up -- a channel name without its NUL
   within the datagram or over 63 characters, a fragment beyond its message's size or
   numbered beyond its count; 1 otherwise (including what is not LCM's at all). */
int shoal_lcm_datagram_ok(const unsigned char *p, size_t n);

/* How many datagrams recvmsg has returned empty because shoal_lcm_datagram_ok refused
   them, in this process. */
unsigned long shoal_lcm_datagrams_refused(void);

#ifdef __cplusplus
}
#endif
