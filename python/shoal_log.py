#!/usr/bin/env python3
"""Reads a Shoal LCM log (shoal sim --out, shoal run, lcm-logger) into plain records.

Standard library only (Python 3.9+); the messages are decoded by the Python types that the
build generates with lcm-gen (build/python/shoal/). docs/analyze.md, "Reading a log from
Python", has the commands. In short:

    python3 build/python/shoal_log.py run.lcmlog            # summary; run.lcmlog.key is used
    python3 build/python/shoal_log.py run.lcmlog --json

    import sys; sys.path.insert(0, "build/python")
    import shoal_log
    log = shoal_log.read_log("run.lcmlog")
    log.states[1][-1].eta          # follower 1's last state: x, y, z, theta, psi

The generated types are looked for in, first to last: the `types_dir` argument (--types
DIR), the environment variable SHOAL_PYTHON_TYPES, the directory of this file (the copy
the build puts into build/python/), and ../build/python from it (the source tree's
python/, next to a build directory named build). Each names the directory that holds the
package `shoal/`.

Authentication (runtime/bus_auth.h, docs/run.md): every message of a run is followed by a
24-byte trailer, the magic b"SHOALSIP" and a 16-byte SipHash-2-4 tag (its 128-bit output)
over the channel name, a NUL and the message's bytes, keyed with 16 bytes derived from the
run's 32-byte key (libsodium's crypto_kdf_derive_from_key, subkey 1, context "SHOALSIP":
BLAKE2b with that salt and personalisation). Logs written by earlier versions carry 40
bytes instead: b"SHOALMAC" and HMAC-SHA-512/256 under the key (its first 32 bytes); both
verify. With the run's key (`<log>.key` next to the log, or key_file) every message on a
Shoal channel must verify: what does not is dropped and counted, as shoal analyze does.
Without a key, trailers are stripped unchecked and the messages counted as unverified.
SipHash is computed by libsodium (ctypes) where it is installed, in Python otherwise.

What is kept and what is counted follows shoal analyze (analysis/run_data.cc): a message
that does not decode to exactly its bytes by the C++ readers' rules is undecodable; an id
beyond the run's followers (the logged scenario's, else the statuses', else 1023, as known
when the message is read) is rejected; a channel status above the largest known is counted
as dropped_invalid; vehicle states and channel decisions at impossible times are left
out (analysis.cc ValidStates, ChannelEventTimeOf); a retimed log's marker is not an event.
The logged scenario is read with tomllib (Python 3.11+); on older Pythons ids are checked against the statuses'
followers and the run's end is judged from the states alone (as shoal analyze does for a
log without scenario text).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import hmac
import importlib
import io
import json
import math
import mmap
import os
import re
import struct
import sys
from dataclasses import dataclass, field
from typing import Dict, Iterator, List, Optional, Tuple

SYNC = 0xEDA1DA01
SYNC_BYTES = struct.pack(">I", SYNC)
HEADER_BYTES = 4 + 8 + 8 + 4 + 4
MAX_CHANNEL = 256          # plausibility limits of an event header (runtime/log_reader.h)
MAX_DATA = 256 << 20
START_SCAN_BYTES = 1 << 20  # a damaged start: the first event is looked for this far
MAX_WARNINGS = 20

MAGIC = b"SHOALSIP"          # what a run writes now: SipHash-2-4, 128-bit tag
MAC_BYTES = 16
TRAILER_BYTES = len(MAGIC) + MAC_BYTES
HMAC_MAGIC = b"SHOALMAC"     # logs of earlier versions: HMAC-SHA-512/256
HMAC_MAC_BYTES = 32
HMAC_TRAILER_BYTES = len(HMAC_MAGIC) + HMAC_MAC_BYTES
KEY_BYTES = 32

TYPES_ENV = "SHOAL_PYTHON_TYPES"

# channel_event_t.status -> the key shoal analyze counts it under.
STATUS_NAMES = {
    0: "delivered", 1: "dropped_loss", 2: "dropped_queue", 3: "dropped_invalid",
    4: "skipped_modem_busy", 5: "dropped_range", 6: "skipped_silent",
    7: "dropped_link_down", 8: "dropped_deaf",
}
NOT_SENT = (4, 6)  # the state was never transmitted: not in `sent`


def status_name(status: int) -> str:
    """The key a status is counted under: a status above the largest this reader knows
    (STATUS_DROPPED_DEAF, 8) is a newer writer's kind of drop, counted as dropped_invalid
    (lcmtypes/README.md); a negative one is rejected when read."""
    return STATUS_NAMES.get(status, "dropped_invalid")


class ShoalLogError(Exception):
    """The log cannot be read at all (missing, empty, not an LCM log, no Shoal message,
    a bad key file, the generated types not found). Damage inside a log is not an error:
    it is in ShoalLog.warnings."""


# ---------------------------------------------------------------------------- records

@dataclass
class State:
    """vehicle_state_t on SHOAL_STATE_<id> (docs: lcmtypes/vehicle_state_t.lcm)."""
    vehicle_id: int
    utime: int                      # [us]
    seq: int
    eta: Tuple[float, ...]          # x, y, z (NED) [m], pitch theta, heading psi [rad]
    nu: Tuple[float, ...]           # u, v, w [m/s], q, r [rad/s] (body frame)
    eta_dot: Tuple[float, ...]
    accel_cmd: Tuple[float, ...]
    tau: Tuple[float, ...]
    flags: int


@dataclass
class Decision:
    """One channel_event_t: a channel decision for one message on one directed link."""
    utime: int
    sender: int
    receiver: int
    msg_seq: int
    send_utime: int                 # [us]
    delay_s: float                  # drawn delay
    deliver_utime: int              # [us], 0 if not delivered
    status: int
    status_name: str                # STATUS_NAMES; dropped_invalid for an unknown status
    reason: str


@dataclass
class Clock:
    """One SHOAL_CLOCK message: ticks tick .. tick + n_ticks - 1 (clock_tick_t: one)."""
    utime: int
    vehicle_id: int
    seq: int
    tick: int
    n_ticks: int
    period_us: int
    final_tick: bool
    n_deliveries: int


@dataclass
class Health:
    """health2_t (or health_t of older logs: the window fields are None; a health2_t
    whose window is not reported, count -1: no bins)."""
    utime: int
    vehicle_id: int                 # -1: the channel emulator
    seq: int
    ticks: int
    lateness_p50_s: float
    lateness_p99_s: float
    lateness_max_s: float
    overruns: int
    msgs_received: int
    msgs_dropped_invalid: int
    msgs_dropped_old: int
    neighbour_timeouts: int
    active_neighbours: int
    saturated_ticks: int
    saturation_fraction: float
    lateness_window_count: Optional[int] = None
    lateness_window_max_s: Optional[float] = None
    lateness_window_bins: Optional[Tuple[int, ...]] = None


@dataclass
class Status:
    """run_status_t on SHOAL_STATUS (the scenario text is kept once, ShoalLog.scenario_toml)."""
    utime: int
    vehicle_id: int                 # -1 emulator, -2 launcher / shoal sim
    seq: int
    state: str
    scenario_name: str
    seed: int
    followers: int
    message: str


@dataclass
class ShoalLog:
    path: str
    key_file: Optional[str] = None  # the key used; None: messages read unverified
    states: Dict[int, List[State]] = field(default_factory=dict)  # by vehicle, by utime
    decisions: List[Decision] = field(default_factory=list)       # in log order
    clock: List[Clock] = field(default_factory=list)
    health: Dict[int, List[Health]] = field(default_factory=dict)
    statuses: List[Status] = field(default_factory=list)
    rx: Dict[int, int] = field(default_factory=dict)  # SHOAL_RX_<id>: messages per receiver
    scenario_toml: Optional[str] = None
    followers: int = 0
    events: int = 0                 # every event read (the unauthenticated ones too; not
                                    # the marker of a retimed log)
    other_events: int = 0           # on channels no Shoal process publishes
    verified: int = 0
    unauthenticated: int = 0        # with a key: no trailer, or it did not verify (dropped)
    unauthenticated_by_channel: Dict[str, int] = field(default_factory=dict)
    unverified: int = 0             # no key: a trailer stripped unchecked
    undecodable: int = 0            # a Shoal channel, but the bytes do not decode
    rejected: int = 0               # decoded, but an id that does not fit (or a health
                                    # window that does not add up)
    repeated_states: int = 0        # same vehicle and utime as an earlier state
    repeated_decisions: int = 0     # in a channel batch whose bytes came before
    repeated_health: int = 0        # a health report whose bytes came before
    # Channel decisions at impossible times (sent at a negative time or after the run's
    # end, delivered before sent or after the last possible delivery), left out of
    # `decisions` and of decision_counts() as shoal analyze leaves them out of its counts.
    damaged_decisions: List[Decision] = field(default_factory=list)
    # Vehicle states at impossible times (a negative time, or after the run's end), left
    # out of `states` as shoal analyze leaves them out of its log_states and its metrics.
    damaged_states: List[State] = field(default_factory=list)
    states_negative_time: int = 0
    states_after_end: int = 0
    decisions_sent_impossible: int = 0
    decisions_delivered_impossible: int = 0
    end_utime: int = -1             # [us] the last possible send time (-1: unknown)
    last_delivery_utime: int = -1   # [us] the last possible delivery time (-1: unknown)
    # A log written by `shoal retime`: its marker event (not counted in `events`), as
    # shoal analyze's retimed_from: {"log", "first_timestamp_us", "last_timestamp_us"}.
    retimed_from: Optional[dict] = None
    insecure_run: bool = False      # a status says the bus was not authenticated
    damaged: bool = False
    warnings: List[str] = field(default_factory=list)

    @property
    def key_used(self) -> bool:
        return self.key_file is not None

    def decision_counts(self) -> Dict[str, int]:
        """Decisions per status as shoal analyze counts them (channel.* of its JSON): an
        unknown status as dropped_invalid, those at impossible times left out."""
        counts = {name: 0 for name in STATUS_NAMES.values()}
        for d in self.decisions:
            counts[d.status_name] += 1
        counts["sent"] = sum(v for s, v in _by_status(self.decisions).items() if s not in NOT_SENT)
        counts["dropped"] = counts["sent"] - counts["delivered"]
        return counts

    def clock_ticks(self) -> int:
        """The distinct ticks the clock messages cover (a window logged twice counts once)."""
        ticks, covered_to = 0, -1
        for first, last in sorted((c.tick, c.tick + c.n_ticks - 1) for c in self.clock):
            if last > covered_to:
                ticks += last - max(first, covered_to + 1) + 1
                covered_to = last
        return ticks


def _by_status(decisions: List[Decision]) -> Dict[int, int]:
    out: Dict[int, int] = {}
    for d in decisions:
        out[d.status] = out.get(d.status, 0) + 1
    return out


# ------------------------------------------------------------------ the generated types

TYPE_NAMES = ("vehicle_state_t", "channel_events_t", "channel_event_t", "clock_window_t",
              "clock_tick_t", "health2_t", "health_t", "run_status_t")


def load_types(types_dir: Optional[str] = None):
    """The generated package `shoal` (lcm-gen -p), from the first place that holds it
    (module docstring). Raises ShoalLogError naming the places looked in, or the package
    that does not import (a damaged file) or lacks a type (a stale build)."""
    here = os.path.dirname(os.path.abspath(__file__))
    if types_dir is not None:  # an explicit directory without the types is an error
        places = [types_dir]
    else:
        places = [p for p in (os.environ.get(TYPES_ENV), here,
                              os.path.join(here, os.pardir, "build", "python")) if p]
    places = [os.path.abspath(p) for p in places]
    for place in places:
        if os.path.isfile(os.path.join(place, "shoal", "__init__.py")):
            return _import_types(place)
    raise ShoalLogError(
        "the generated Python message types (package shoal/, made by the build with "
        "lcm-gen -p) are not in " + ", ".join(places) + ": build Shoal (cmake --build "
        "build) and run build/python/shoal_log.py, or give --types DIR or " + TYPES_ENV +
        "=DIR, DIR being the directory that holds shoal/")


_REBUILD = ("make them again (cmake --build build), or give --types DIR, DIR being the "
            "directory of a build's package shoal/")


def _origin(module) -> str:
    return os.path.dirname(os.path.abspath(getattr(module, "__file__", "") or ""))


def _forget_package(package_dir: str) -> None:
    """Unloads the modules of a package that failed, so that another place can be tried."""
    for name in [n for n in sys.modules if n == "shoal" or n.startswith("shoal.")]:
        if _origin(sys.modules[name]) == package_dir or name == "shoal":
            del sys.modules[name]


def _usable_type(cls) -> bool:
    try:
        return callable(getattr(cls, "decode")) and len(cls._get_packed_fingerprint()) == 8
    except Exception:  # noqa: BLE001  whatever a damaged module does: not usable
        return False


def _import_types(place: str):
    package_dir = os.path.join(place, "shoal")
    loaded = sys.modules.get("shoal")
    if loaded is not None and _origin(loaded) != package_dir:
        raise ShoalLogError("a module named shoal from " + _origin(loaded) + " is already "
                            "loaded; the message types in " + place + " cannot be imported "
                            "beside it")
    added = place not in sys.path
    if added:
        sys.path.insert(0, place)
    try:
        package = importlib.import_module("shoal")
    except Exception as e:  # noqa: BLE001  a syntax error, a missing module, ...
        _forget_package(package_dir)
        if added:
            sys.path.remove(place)
        what = " ".join(("%s: %s" % (type(e).__name__, e)).split())
        raise ShoalLogError("%s: the generated Python message types do not import (%s); %s"
                            % (package_dir, what, _REBUILD)) from None
    if _origin(package) != package_dir:
        raise ShoalLogError("a module named shoal from " + _origin(package) + " is already "
                            "loaded; the message types in " + place + " cannot be imported "
                            "beside it")
    missing = [n for n in TYPE_NAMES if not _usable_type(getattr(package, n, None))]
    if missing:
        _forget_package(package_dir)
        if added:
            sys.path.remove(place)
        raise ShoalLogError("%s: the generated Python message types lack %s (made by an "
                            "older build?); %s" % (package_dir, ", ".join(missing), _REBUILD))
    return package


# The wire rules of the C++ readers (runtime/lcm_bus.h Decode: ArrayCountsFit,
# StringLengthsFit; analysis/run_data.cc DecodeChannelEvents), checked before the generated
# decoder runs: it reads what the fields ask for from a buffer, so a string length that runs
# past the end, or a string whose last byte is not its NUL, would go unnoticed.
_I32 = struct.Struct(">i")
_STATE_BYTES = 8 + 8 + 4 + 4 + 5 * 5 * 8 + 4
_EVENT_BODY = 8 + 4 * 5 + 8 * 3 + 1   # channel_event_t without its hash, before `reason`
_BATCH_HEADER = 8 + 8 + 4 + 4 + 4


def _skip_string(data: bytes, pos: int) -> int:
    """runtime/lcm_bus.h wire_check::SkipString: the position after the string at pos, or
    -1: a length in [1, bytes left], the text without NUL, then one NUL."""
    if pos + 4 > len(data):
        return -1
    n = _I32.unpack_from(data, pos)[0]
    pos += 4
    if n < 1 or n > len(data) - pos or data[pos + n - 1] != 0 or \
            data.find(b"\0", pos, pos + n - 1) >= 0:
        return -1
    return pos + n


def _event_body(data: bytes, pos: int) -> int:
    """run_data.cc DecodeEventBody: the position after the event body at pos, or -1 (its
    reason's length in [1, bytes left], its last byte a NUL; an inner NUL is not checked)."""
    if len(data) - pos < _EVENT_BODY + 4:
        return -1
    n = _I32.unpack_from(data, pos + _EVENT_BODY)[0]
    start = pos + _EVENT_BODY + 4
    if n < 1 or n > len(data) - start or data[start + n - 1] != 0:
        return -1
    return start + n


def _array_fits(data: bytes, fixed: int, per_item: int) -> bool:
    """ArrayCountsFit of the clock types: the count (the last fixed field) >= 0, and the
    bytes exactly the fixed part and that many items."""
    if len(data) < fixed:
        return False
    n = _I32.unpack_from(data, fixed - 4)[0]
    return n >= 0 and len(data) - fixed == n * per_item


def _wire_ok(name: str, data: bytes) -> bool:
    if name == "vehicle_state_t":
        return len(data) == _STATE_BYTES
    if name == "channel_event_t":
        return _event_body(data, 8) == len(data)
    if name == "channel_events_t":
        if len(data) < _BATCH_HEADER:
            return False
        n = _I32.unpack_from(data, _BATCH_HEADER - 4)[0]
        if n < 0 or n > (len(data) - _BATCH_HEADER) // (_EVENT_BODY + 5):
            return False
        pos = _BATCH_HEADER
        for _ in range(n):
            pos = _event_body(data, pos)
            if pos < 0:
                return False
        return pos == len(data)
    if name == "clock_window_t":
        return _array_fits(data, 8 + 8 + 4 + 4 + 8 + 4 + 8 + 1 + 4, 8 + 4 + 4 + 4 + 8)
    if name == "clock_tick_t":
        return _array_fits(data, 8 + 8 + 4 + 4 + 8 + 8 + 1 + 4, 4 + 4 + 4 + 8)
    if name == "run_status_t":
        pos = 8 + 8 + 4 + 4
        for _ in range(3):  # state, scenario_name, scenario_toml
            pos = _skip_string(data, pos)
            if pos < 0:
                return False
        return _skip_string(data, pos + 8 + 4) >= 0  # after seed and followers: message
    return True  # health2_t, health_t: fixed size, checked by the decoded length


class _Decoder:
    """Decodes by fingerprint, through the generated code, after the C++ readers' wire
    checks (_wire_ok); a message must decode to exactly its bytes, else it is undecodable."""

    def __init__(self, types):
        self.t = types
        self.by_hash = {}
        for name in TYPE_NAMES:
            cls = getattr(types, name)
            self.by_hash[cls._get_packed_fingerprint()] = (name, cls)

    def decode(self, data: bytes, accepted: Tuple[str, ...]):
        name, cls = self.by_hash.get(bytes(data[:8]), (None, None))
        if cls is None or name not in accepted or not _wire_ok(name, data):
            return None
        buf = io.BytesIO(data)
        try:
            msg = cls.decode(buf)
        except Exception:  # noqa: BLE001  whatever garbage makes it raise is undecodable
            return None
        return msg if buf.tell() == len(data) else None


# ----------------------------------------------------------------------- the event log

def _plausible_header(mm, pos: int, size: int) -> bool:
    """A sync word, sane lengths and a printable channel (as far as the file goes)."""
    if size - pos < HEADER_BYTES or mm[pos:pos + 4] != SYNC_BYTES:
        return False
    cl, dl = struct.unpack_from(">ii", mm, pos + 20)
    if cl < 1 or cl > MAX_CHANNEL or dl < 0 or dl > MAX_DATA:
        return False
    name = mm[pos + HEADER_BYTES:min(size, pos + HEADER_BYTES + cl)]
    return all(0x20 <= c <= 0x7E for c in name)


def _check_event(mm, pos: int, size: int) -> str:
    """'valid', or what is wrong with the event at pos (runtime/log_reader.cc's rules)."""
    if size - pos < HEADER_BYTES:
        avail = size - pos
        return "cut" if mm[pos:pos + min(avail, 4)] == SYNC_BYTES[:min(avail, 4)] else "sync"
    if mm[pos:pos + 4] != SYNC_BYTES:
        return "sync"
    cl, dl = struct.unpack_from(">ii", mm, pos + 20)
    if cl < 1 or cl > MAX_CHANNEL or dl < 0 or dl > MAX_DATA:
        return "header"
    total = HEADER_BYTES + cl + dl
    if total > size - pos:
        return "cut"
    if not all(0x20 <= c <= 0x7E for c in mm[pos + HEADER_BYTES:pos + HEADER_BYTES + cl]):
        return "header"
    # The next event should start right after this one. If it does not, and a plausible
    # header lies inside this one, this one's lengths are damaged: it swallows a real event.
    end = pos + total
    if end + 4 <= size and mm[end:end + 4] != SYNC_BYTES:
        k = mm.find(SYNC_BYTES, pos + 1, end)
        while k >= 0:
            if _plausible_header(mm, k, size):
                return "not_followed"
            k = mm.find(SYNC_BYTES, k + 1, end)
    return "valid"


_WHAT = {"sync": "no sync word", "header": "an implausible event header",
         "cut": "an event cut short by the end of the file",
         "not_followed": "an event whose lengths do not lead to the next event"}


def _resync(mm, pos: int, size: int, limit: int = -1) -> int:
    """The offset of the next valid event after pos (within limit bytes if >= 0), or -1."""
    k = mm.find(SYNC_BYTES, pos + 1)
    while k >= 0 and (limit < 0 or k - pos < limit):
        if _check_event(mm, k, size) == "valid":
            return k
        k = mm.find(SYNC_BYTES, k + 1)
    return -1


class _EventReader:
    """Events of an LCM log file: (timestamp, channel, data). Damage is warned about and
    skipped (resynchronised at the next valid event) or stops the reading, as shoal
    analyze's reader does; a file that holds no event raises ShoalLogError."""

    def __init__(self, path: str):
        self.path = path
        self.warnings: List[str] = []
        self.damaged_regions = 0
        if os.path.exists(path) and not os.path.isfile(path):  # a FIFO would block
            raise ShoalLogError(path + ": not a log (not a regular file)")
        try:
            with open(path, "rb") as f:
                self.size = os.fstat(f.fileno()).st_size
                if self.size == 0:
                    raise ShoalLogError(path + ": empty file (0 bytes), not an LCM log")
                self.mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except OSError as e:
            raise ShoalLogError(path + ": cannot read log (" + e.strerror + ")") from None
        if self.size < HEADER_BYTES:
            raise ShoalLogError("%s: %d bytes, too short to hold one LCM log event "
                                "(%d-byte header); not an LCM log" % (path, self.size, HEADER_BYTES))
        self.start = 0
        if _check_event(self.mm, 0, self.size) not in ("valid", "cut"):
            self.start = _resync(self.mm, 0, self.size, START_SCAN_BYTES)
            if self.start < 0:
                raise ShoalLogError("%s: not an LCM log (no LCM event header with sync word "
                                    "0xEDA1DA01 in its first %d bytes)"
                                    % (path, min(START_SCAN_BYTES, self.size)))
            self._warn("the file does not start with an LCM event (damaged start): skipped "
                       "%d bytes to the first event, at byte %d" % (self.start, self.start))

    def _warn(self, text: str) -> None:
        self.damaged_regions += 1
        if self.damaged_regions <= MAX_WARNINGS:
            self.warnings.append(self.path + ": " + text)
        elif self.damaged_regions == MAX_WARNINGS + 1:
            self.warnings.append("%s: more damaged places follow (only the first %d are "
                                 "listed)" % (self.path, MAX_WARNINGS))

    def __iter__(self) -> Iterator[Tuple[int, str, bytes]]:
        mm, size, pos = self.mm, self.size, self.start
        while pos < size:
            what = _check_event(mm, pos, size)
            if what == "valid":
                timestamp, cl, dl = struct.unpack_from(">qii", mm, pos + 12)
                channel = mm[pos + HEADER_BYTES:pos + HEADER_BYTES + cl].decode("ascii")
                data = mm[pos + HEADER_BYTES + cl:pos + HEADER_BYTES + cl + dl]
                pos += HEADER_BYTES + cl + dl
                yield timestamp, channel, data
                continue
            nxt = _resync(mm, pos, size)
            if nxt >= 0:
                self._warn("damaged at byte %d (%s): skipped %d bytes, resynchronised at the "
                           "next valid event, at byte %d" % (pos, _WHAT[what], nxt - pos, nxt))
                pos = nxt
            elif what == "cut":
                self._warn("truncated: the last event, at byte %d, is cut short by the end of "
                           "the file (%d bytes left); analysed up to byte %d"
                           % (pos, size - pos, pos))
                return
            else:
                self._warn("damaged at byte %d (%s) and no valid event follows; stopped "
                           "there, %d bytes not analysed" % (pos, _WHAT[what], size - pos))
                return

    def close(self) -> None:
        self.mm.close()


# ------------------------------------------------------------------- authentication

def read_key_file(path: str) -> bytes:
    """A run's key file: 64 hex digits (white space around them allowed)."""
    try:
        if not os.path.isfile(path):
            raise ShoalLogError(path + ": not a key file (not a regular file)")
        with open(path, "rb") as f:
            text = f.read(4097)
    except OSError as e:
        raise ShoalLogError(path + ": cannot read the key file (" + e.strerror + ")") from None
    text = text.strip(b" \t\r\n")
    if len(text) != 2 * KEY_BYTES or not re.fullmatch(rb"[0-9a-fA-F]+", text):
        raise ShoalLogError(path + ": the key is not 64 hex digits (got %d characters)"
                            % len(text))
    return bytes.fromhex(text.decode("ascii"))


_MASK = (1 << 64) - 1


def _rotl(x: int, b: int) -> int:
    return ((x << b) | (x >> (64 - b))) & _MASK


def _sip_rounds(v: List[int], n: int) -> None:
    v0, v1, v2, v3 = v
    for _ in range(n):
        v0 = (v0 + v1) & _MASK
        v1 = _rotl(v1, 13) ^ v0
        v0 = _rotl(v0, 32)
        v2 = (v2 + v3) & _MASK
        v3 = _rotl(v3, 16) ^ v2
        v0 = (v0 + v3) & _MASK
        v3 = _rotl(v3, 21) ^ v0
        v2 = (v2 + v1) & _MASK
        v1 = _rotl(v1, 17) ^ v2
        v2 = _rotl(v2, 32)
    v[:] = [v0, v1, v2, v3]


def siphash128_python(key: bytes, data: bytes) -> bytes:
    """SipHash-2-4 with its 128-bit output (libsodium's crypto_shorthash_siphashx24)."""
    k0, k1 = struct.unpack("<QQ", key)
    v = [0x736F6D6570736575 ^ k0, 0x646F72616E646F6D ^ k1 ^ 0xEE,
         0x6C7967656E657261 ^ k0, 0x7465646279746573 ^ k1]
    full = len(data) // 8 * 8
    last = int.from_bytes(data[full:], "little") | ((len(data) & 0xFF) << 56)
    for m in list(struct.unpack_from("<%dQ" % (full // 8), data)) + [last]:
        v[3] ^= m
        _sip_rounds(v, 2)
        v[0] ^= m
    v[2] ^= 0xEE
    _sip_rounds(v, 4)
    out = struct.pack("<Q", v[0] ^ v[1] ^ v[2] ^ v[3])
    v[1] ^= 0xDD
    _sip_rounds(v, 4)
    return out + struct.pack("<Q", v[0] ^ v[1] ^ v[2] ^ v[3])


def _libsodium_siphash128():
    """libsodium's crypto_shorthash_siphashx24 through ctypes, or None."""
    try:
        import ctypes
        import ctypes.util
        name = ctypes.util.find_library("sodium")
        lib = ctypes.CDLL(name or "libsodium.so.23")
        if lib.sodium_init() < 0:
            return None
        fn = lib.crypto_shorthash_siphashx24
        fn.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_ulonglong, ctypes.c_char_p]
    except (OSError, AttributeError):
        return None

    def siphash(key: bytes, data: bytes) -> bytes:
        out = ctypes.create_string_buffer(16)
        fn(out, bytes(data), len(data), key)
        return out.raw
    return siphash


siphash128 = _libsodium_siphash128() or siphash128_python


class Verifier:
    """The trailers of runtime/bus_auth.cc: SipHash-2-4 (128-bit) under a key derived from
    the run's; HMAC-SHA-512/256 under the run's key for logs of earlier versions."""

    def __init__(self, key: bytes):
        if len(key) != KEY_BYTES:
            raise ShoalLogError("a run's key is %d bytes, not %d" % (KEY_BYTES, len(key)))
        self.sip_key = hashlib.blake2b(b"", digest_size=16, key=key,
                                       salt=struct.pack("<Q", 1) + bytes(8),
                                       person=b"SHOALSIP" + bytes(8)).digest()
        self.keyed = hmac.new(key, digestmod=hashlib.sha512)  # after the key's pads

    def mac(self, channel: str, payload: bytes) -> bytes:
        return siphash128(self.sip_key, channel.encode("ascii") + b"\0" + bytes(payload))

    def hmac_mac(self, channel: str, payload: bytes) -> bytes:
        h = self.keyed.copy()
        h.update(channel.encode("ascii") + b"\0")
        h.update(payload)
        return h.digest()[:HMAC_MAC_BYTES]

    def sign(self, channel: str, payload: bytes) -> bytes:
        return bytes(payload) + MAGIC + self.mac(channel, payload)

    def verify(self, channel: str, data: bytes) -> Optional[bytes]:
        """The message without its trailer if the trailer verifies for channel, else None."""
        n = trailer_bytes(data)
        if n == 0:
            return None
        payload = data[:-n]
        mac = self.mac(channel, payload) if n == TRAILER_BYTES else self.hmac_mac(channel, payload)
        return payload if hmac.compare_digest(mac, data[-(n - len(MAGIC)):]) else None


def trailer_bytes(data: bytes) -> int:
    """The size of the trailer data ends with, by its magic (unverified), or 0."""
    if len(data) >= TRAILER_BYTES and data[-TRAILER_BYTES:-MAC_BYTES] == MAGIC:
        return TRAILER_BYTES
    if len(data) >= HMAC_TRAILER_BYTES and data[-HMAC_TRAILER_BYTES:-HMAC_MAC_BYTES] == HMAC_MAGIC:
        return HMAC_TRAILER_BYTES
    return 0


def has_trailer(data: bytes) -> bool:
    return trailer_bytes(data) > 0


# ------------------------------------------------------------------------- channels

_ID = r"(-[0-9]{1,6}|[0-9]{1,7})"  # runtime/channels.h: at most 7 characters
_CHANNEL_RE = re.compile(r"SHOAL_(?:(STATE|RX|HEALTH)_" + _ID + r"|(CHANNEL|CLOCK|STATUS))\Z")


def parse_channel(channel: str) -> Tuple[str, int]:
    """('STATE' | 'RX' | 'HEALTH', id), ('CHANNEL' | 'CLOCK' | 'STATUS', 0), ('', 0) for a
    channel no Shoal process publishes."""
    m = _CHANNEL_RE.match(channel)
    if m is None:
        return "", 0
    if m.group(1):
        return m.group(1), int(m.group(2))
    return m.group(3), 0


# ------------------------------------------------------------------------ the reader

MAX_VEHICLE_ID = 1023     # the largest id accepted when nothing says n (run_data.h)
INT64_MAX = (1 << 63) - 1


@dataclass
class _Scenario:
    """What the reading needs of the logged scenario (shoal analyze parses all of it)."""
    followers: int
    period_us: int
    final_tick: int
    largest_delay_us: int      # analysis.cc LargestDelayUs


class _NotLoaded(Exception):
    pass


def _number(table, key, default=None) -> float:
    v = table.get(key, default) if isinstance(table, dict) else None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _NotLoaded(key)
    return float(v)


def _trace_max(file) -> float:
    """The largest delay of a delay trace (scenario/loader.cc ParseTraceText): a log's
    scenario text resolves a relative file in the working directory, as shoal analyze."""
    if not isinstance(file, str) or not file:
        raise _NotLoaded("file")
    try:
        with open(file, "r", encoding="utf-8", errors="replace") as f:
            lines = f.read(64 << 20).splitlines()
    except OSError:
        raise _NotLoaded(file) from None
    times: List[float] = []
    delays: List[float] = []
    for line in lines:
        line = line.split("#", 1)[0]
        if not line.strip(" \t\r"):
            continue
        fields = line.split(",")
        if len(fields) != 2:
            raise _NotLoaded(file)
        try:
            t, d = float(fields[0]), float(fields[1])
        except ValueError:
            if not times and "".join(line.split()) == "t_s,delay_s":
                continue
            raise _NotLoaded(file) from None
        if not all(math.isfinite(x) and 0 <= x <= 1e9 for x in (t, d)) or \
                (times and not t > times[-1]):
            raise _NotLoaded(file)
        times.append(t)
        delays.append(d)
    if not delays:
        raise _NotLoaded(file)
    return max(delays)


def _delay_bound(table) -> float:
    """max(MaxDelaySeconds(c), base_s + |amplitude_s|) of one delay table (0: none)."""
    if not isinstance(table, dict):
        raise _NotLoaded("delay")
    model = table.get("model", "none")
    if model == "none":
        return 0.0
    if model == "acoustic":
        return (_number(table, "max_range_m") / _number(table, "sound_speed_mps", 1500.0) +
                _number(table, "processing_s", 0.0) + _number(table, "jitter_s", 0.0))
    if model == "trace":
        return _trace_max(table.get("file"))
    base = _number(table, "base_s")
    if model == "constant":
        return base
    if model in ("sinusoid", "uniform"):
        amplitude = _number(table, "amplitude_s")
        return max(base + amplitude, base + abs(amplitude))
    raise _NotLoaded("model")


def _ids(value, n: int) -> Optional[List[int]]:
    """A list of follower ids, each an int in 1..n, or None."""
    if not isinstance(value, list):
        return None
    if any(isinstance(i, bool) or not isinstance(i, int) or not 1 <= i <= n for i in value):
        return None
    return value


def _swarm_loads(swarm: dict, control: dict, n: int) -> bool:
    """What scenario/loader.cc requires of the follower graph and offsets, which every count
    of the log depends on: leader_links distinct ids in 1..n, not empty; edges distinct
    pairs of distinct ids in 1..n; every follower reached from the leader (Assumption 1);
    offsets_m, if given, one per follower. A logged text damaged in its follower count
    fails one of these, as shoal analyze's loader refuses it."""
    links = _ids(swarm.get("leader_links"), n)
    if not links or len(set(links)) != len(links):
        return False
    edges = swarm.get("edges", [])
    if not isinstance(edges, list):
        return False
    pairs = []
    for e in edges:
        pair = _ids(e, n)
        if pair is None or len(pair) != 2 or pair[0] == pair[1]:
            return False
        pairs.append((pair[0], pair[1]))
    if len(set(pairs)) != len(pairs):
        return False
    reached, frontier = set(links), list(links)
    while frontier:  # [i, j]: i receives from j
        j = frontier.pop()
        for i, k in pairs:
            if k == j and i not in reached:
                reached.add(i)
                frontier.append(i)
    if len(reached) != n:
        return False
    offsets = control.get("offsets_m")
    return offsets is None or (isinstance(offsets, list) and len(offsets) == n)


def _read_scenario(text: str) -> Optional[_Scenario]:
    """The logged scenario's followers, control period, last tick and largest delay, or
    None if it does not load. Needs tomllib (Python 3.11+): without it every log is read
    as shoal analyze reads one without scenario text."""
    try:
        import tomllib
    except ImportError:
        return None
    try:
        root = tomllib.loads(text)
        run = root.get("run", {})
        swarm = root.get("swarm", {})
        channel = root.get("channel", {})
        followers = swarm.get("followers") if isinstance(swarm, dict) else None
        if isinstance(followers, bool) or not isinstance(followers, int) or \
                not 1 <= followers <= 1000 or not isinstance(channel, dict):
            return None
        control = root.get("control", {})
        if not isinstance(control, dict) or not _swarm_loads(swarm, control, followers):
            return None
        duration = _number(run, "duration_s", 600.0)
        rate = _number(run, "control_rate_hz", 50.0)
        if not (duration > 0 and rate > 0 and duration * rate >= 1.0):
            return None
        period_us = int(1e6 / rate + 0.5)
        final_tick = int(math.floor(duration * 1e6 / float(period_us) + 1e-9))
        worst = _delay_bound(channel.get("delay", {}))
        for link in channel.get("link", []):
            if isinstance(link, dict) and "delay" in link:
                worst = max(worst, _delay_bound(link["delay"]))
        for event in root.get("event", []):
            if isinstance(event, dict) and event.get("kind") == "channel" and "delay" in event:
                worst = max(worst, _delay_bound(event["delay"]))
    except (_NotLoaded, ValueError, TypeError, AttributeError, ZeroDivisionError,
            OverflowError, RecursionError):
        return None
    us = math.ceil(worst * 1e6) + 1.0
    return _Scenario(followers, period_us, final_tick, int(us) if us < 9e18 else INT64_MAX)


def _has_tomllib() -> bool:
    try:
        import tomllib  # noqa: F401
    except ImportError:
        return False
    return True


def _saturating_add(a: int, b: int) -> int:
    return INT64_MAX if a > INT64_MAX - b else a + b


def _control_period(scenario: Optional[_Scenario], clock: List[Clock],
                    leader: List[State]) -> int:
    """analysis.cc ControlPeriodOf: the scenario's, else the clock's, else the median of
    the leader's first steps."""
    if scenario is not None:
        return scenario.period_us
    if clock and clock[0].period_us > 0:
        return clock[0].period_us
    dt = [leader[k].utime - leader[k - 1].utime for k in range(1, min(len(leader), 1000))
          if leader[k - 1].utime >= 0]
    return sorted(dt)[len(dt) // 2] if dt else 0


def _contiguous_reach(states: List[State], period: int) -> int:
    """analysis.cc ContiguousReach: how far the states run from time 0 on without a gap of
    more than a minute (and 1000 periods); -1 if none is at a time >= 0."""
    gap = 60000000 if period <= 60000 else 1000 * period if period < 60000000 else INT64_MAX
    times = [s.utime for s in states if s.utime >= 0]
    if not times:
        return -1
    reach = times[0]
    for t in times[1:]:
        if t - reach > gap:
            break
        reach = t
    return reach


def _time_bounds(log: ShoalLog, scenario: Optional[_Scenario]) -> Tuple[int, int]:
    """analysis.cc StateTimeBoundsOf: the last possible send time of a channel decision and
    the last possible delivery time (-1: unknown)."""
    period = _control_period(scenario, log.clock, log.states.get(0, []))
    reach = sorted(r for r in (_contiguous_reach(s, period) for s in log.states.values())
                   if r >= 0)
    majority = reach[len(reach) - (len(reach) // 2 + 1)] if reach else -1
    limit = -1
    if scenario is not None:
        limit = max(scenario.final_tick * scenario.period_us, majority)
    elif majority >= 0:
        limit = _saturating_add(majority, max(majority, period))
    if limit < 0:
        return -1, -1
    # A run that ran to its final tick (a clock's final window, or a run-level "finished"
    # status) has nothing after it: a run shortened with --duration ends there.
    end = next((c.utime + (c.n_ticks - 1) * c.period_us for c in reversed(log.clock)
                if c.final_tick and 0 <= c.utime + (c.n_ticks - 1) * c.period_us <= limit), None)
    if end is None:
        for st in reversed(log.statuses):
            if st.vehicle_id < 0 and st.state in ("finished", "interrupted", "failed") and \
                    0 <= st.utime <= limit:
                end = st.utime if st.state == "finished" else None
                break
    if end is not None:
        limit = end
    delay = scenario.largest_delay_us if scenario is not None else limit
    return limit, _saturating_add(_saturating_add(limit, delay), max(period, 0))


def _impossible(d: Decision, limit: int, deliver_limit: int) -> str:
    """analysis.cc ChannelEventTimeOf: '' possible, 'sent' or 'delivered' impossible."""
    if d.send_utime < 0 or (limit >= 0 and d.send_utime > limit):
        return "sent"
    if d.status != 0:
        return ""
    if d.deliver_utime < d.send_utime or (deliver_limit >= 0 and d.deliver_utime > deliver_limit):
        return "delivered"
    return ""


class _Builder:
    """Decodes events into a ShoalLog, keeping what shoal analyze keeps (docs/analyze.md,
    "What it reads", analysis/run_data.cc); what does not decode, or names an id that does
    not fit, is counted. The ids are checked against the limit known when the message is
    read, as RunDataBuilder::IdLimit: the scenario's followers once the logged scenario
    loads, else the largest followers of the statuses so far, else 1023."""

    def __init__(self, log: ShoalLog, types, keep: Tuple[str, ...]):
        self.log = log
        self.dec = _Decoder(types)
        self.keep = keep
        # What must be read for what is kept: the statuses give n and the scenario; the
        # states give n otherwise, and with the clock the times a state or a decision can
        # have (a run's final clock tick is where it ended).
        self.read = set(keep) | {"STATUS", "STATE"}
        if "CHANNEL" in keep or "STATE" in keep:
            self.read.add("CLOCK")
        self.state_ids_only = "STATE" not in keep and "CHANNEL" not in keep
        self.state_counts: Dict[int, int] = {}  # states_ids_only: valid states per id
        self.other_scenarios = 0  # scenario texts that differ from the first one
        self.state_hash = types.vehicle_state_t._get_packed_fingerprint()
        self.max_status_followers = 0
        self.scenario: Optional[_Scenario] = None
        self.warnings: List[str] = []          # as RunDataBuilder's
        self.damaged_warnings: List[str] = []  # what shoal analyze's text says as DAMAGED:
        self.any_shoal = False
        # (kind, publisher, number, hash of the bytes) of each channel batch and health
        # report: the same again is a copy (a log recorded twice, a replay), counted once;
        # the same number with other bytes is a restarted publisher's and is new.
        self.seen: set = set()
        self.handlers = {"STATE": self._state, "RX": self._rx, "HEALTH": self._health,
                         "CHANNEL": self._channel, "CLOCK": self._clock,
                         "STATUS": self._status}

    def id_limit(self) -> int:
        if self.scenario is not None:
            return self.scenario.followers
        if self.max_status_followers > 0:
            return self.max_status_followers
        return MAX_VEHICLE_ID

    def add(self, kind: str, cid: int, data: bytes) -> None:
        if not kind:
            self.log.other_events += 1
        elif kind in self.read:
            self.handlers[kind](cid, data)

    def _decode(self, data: bytes, *accepted: str):
        msg = self.dec.decode(data, accepted)
        if msg is None:
            self.log.undecodable += 1
        return msg

    def _state(self, cid: int, data: bytes) -> None:
        if self.state_ids_only:  # what the decoder checks of a state, without decoding it
            if len(data) != _STATE_BYTES or bytes(data[:8]) != self.state_hash:
                self.log.undecodable += 1
            elif _I32.unpack_from(data, 16)[0] != cid or not 0 <= cid <= self.id_limit():
                self.log.rejected += 1
            else:
                self.state_counts[cid] = self.state_counts.get(cid, 0) + 1
            return
        m = self._decode(data, "vehicle_state_t")
        if m is None:
            return
        if m.vehicle_id != cid or cid < 0 or cid > self.id_limit():
            self.log.rejected += 1
            return
        self.log.states.setdefault(cid, []).append(State(
            m.vehicle_id, m.utime, m.seq, tuple(m.eta), tuple(m.nu), tuple(m.eta_dot),
            tuple(m.accel_cmd), tuple(m.tau), m.flags))

    def _rx(self, cid: int, data: bytes) -> None:
        if not 0 <= cid <= self.id_limit():
            self.log.rejected += 1
            return
        self.log.rx[cid] = self.log.rx.get(cid, 0) + 1

    def _channel(self, cid: int, data: bytes) -> None:
        m = self._decode(data, "channel_events_t", "channel_event_t")
        if m is None:
            return
        events = m.events if hasattr(m, "events") else [m]
        if self._seen_before("CHANNEL", m.vehicle_id, m.seq, data):
            self.log.repeated_decisions += len(events)
            return
        lim = self.id_limit()
        for e in events:
            # A status above the largest known (STATUS_DROPPED_DEAF) is a newer writer's
            # kind of drop: kept, counted as dropped_invalid (lcmtypes/README.md).
            if not (0 <= e.sender <= lim and 0 <= e.receiver <= lim) or e.status < 0:
                self.log.rejected += 1
                continue
            self.log.decisions.append(Decision(
                e.utime, e.sender, e.receiver, e.msg_seq, e.send_utime, e.delay_s,
                e.deliver_utime, e.status, status_name(e.status), e.reason))

    def _seen_before(self, kind: str, publisher: int, number: int, data: bytes) -> bool:
        key = (kind, publisher, number, hash(bytes(data)))
        if key in self.seen:
            return True
        self.seen.add(key)
        return False

    def _clock(self, cid: int, data: bytes) -> None:
        m = self._decode(data, "clock_window_t", "clock_tick_t")
        if m is None:
            return
        n_ticks = getattr(m, "n_ticks", 1)
        if n_ticks < 1 or n_ticks > 100000 or not 0 < m.period_us <= 10 ** 9 or \
                not 0 <= m.tick <= 2 ** 40 or m.utime != m.tick * m.period_us or \
                (m.tick + n_ticks) * m.period_us > 2 ** 62 - 1:  # shoal analyze's limits
            self.log.rejected += 1
            return
        self.log.clock.append(Clock(m.utime, m.vehicle_id, m.seq, m.tick, n_ticks, m.period_us,
                                    m.final_tick != 0, m.n_deliveries))

    def _health(self, cid: int, data: bytes) -> None:
        m = self._decode(data, "health2_t", "health_t")
        if m is None:
            return
        count = getattr(m, "lateness_window_count", None)
        bins = tuple(m.lateness_window_bins) if count is not None and count >= 0 else None
        if m.vehicle_id != cid or not -1 <= cid <= self.id_limit() or (
                count is not None and not _window_ok(count, m.lateness_window_max_s, bins)):
            self.log.rejected += 1
            return
        if self._seen_before("HEALTH", cid, m.utime, data):
            self.log.repeated_health += 1
            return
        self.log.health.setdefault(cid, []).append(Health(
            m.utime, m.vehicle_id, m.seq, m.ticks, m.lateness_p50_s, m.lateness_p99_s,
            m.lateness_max_s, m.overruns, m.msgs_received, m.msgs_dropped_invalid,
            m.msgs_dropped_old, m.neighbour_timeouts, m.active_neighbours, m.saturated_ticks,
            m.saturation_fraction, count, getattr(m, "lateness_window_max_s", None), bins))

    def _status(self, cid: int, data: bytes) -> None:
        m = self._decode(data, "run_status_t")
        if m is None:
            return
        self.log.statuses.append(Status(m.utime, m.vehicle_id, m.seq, m.state,
                                        m.scenario_name, m.seed, m.followers, m.message))
        if 0 < m.followers <= MAX_VEHICLE_ID:
            self.max_status_followers = max(self.max_status_followers, m.followers)
        if m.scenario_toml and self.log.scenario_toml is not None and \
                m.scenario_toml != self.log.scenario_toml:
            self.other_scenarios += 1  # another run's log was joined to this one
        if m.scenario_toml and self.log.scenario_toml is None:
            self.log.scenario_toml = m.scenario_toml
            self.scenario = _read_scenario(m.scenario_toml)
            if self.scenario is None and _has_tomllib():
                self.warnings.append(
                    "the scenario text in the log does not load; its run's bounds are "
                    "judged as for a log without one")

    def finish(self) -> None:
        """n (the scenario's, else the statuses', else the largest id), states beyond it
        rejected, each vehicle's states sorted by time with one per utime (the last
        recorded kept), then the channel decisions at impossible times left out (as shoal
        analyze's analysis leaves them out) and what was not asked for dropped."""
        log = self.log
        ids = self.state_counts if self.state_ids_only else log.states
        if self.scenario is not None:
            n = self.scenario.followers
        elif self.max_status_followers > 0:
            n = self.max_status_followers
        else:
            n = max(ids, default=0)
        log.followers = n
        for vid in [v for v in ids if v > n]:
            gone = ids.pop(vid)
            log.rejected += gone if isinstance(gone, int) else len(gone)
        for vid, states in log.states.items():
            states.sort(key=lambda s: s.utime)  # stable: equal times keep the log's order
            unique: List[State] = []
            for s in states:
                if unique and unique[-1].utime == s.utime:
                    unique[-1] = s
                    log.repeated_states += 1
                else:
                    unique.append(s)
            log.states[vid] = unique
        log.states = dict(sorted(log.states.items()))
        log.health = dict(sorted(log.health.items()))
        if log.repeated_states:
            self.warnings.append(
                "%d vehicle states appear more than once (same vehicle and time: a log "
                "recorded twice or concatenated, or replayed onto a recording bus); each is "
                "counted once, the last copy kept" % log.repeated_states)
        if self.other_scenarios:
            self.warnings.append(
                "%d runs' scenario texts differ in this log (logs of different runs joined "
                "into one): the first one's scenario is used, and the states, decisions and "
                "health of every run are read as one run's" % (self.other_scenarios + 1))
        if log.repeated_decisions or log.repeated_health:
            self.warnings.append(
                "%d channel decisions and %d health reports appear more than once (the same "
                "message from the same publisher: a log recorded twice or concatenated, or "
                "replayed onto a recording bus); each is counted once"
                % (log.repeated_decisions, log.repeated_health))
        log.insecure_run = any("bus not authenticated (--insecure)" in s.message
                               for s in log.statuses)
        # Whether the log holds a Shoal message at all (LoadRunLog's any_shoal).
        self.any_shoal = bool(ids or log.decisions or log.health or log.clock or log.statuses)
        if not self.state_ids_only:
            self._leave_out_impossible_times()
        for kind, attr, empty in (("STATE", "states", {}), ("CHANNEL", "decisions", []),
                                  ("CLOCK", "clock", []), ("HEALTH", "health", {}),
                                  ("STATUS", "statuses", []), ("RX", "rx", {})):
            if kind not in self.keep:
                setattr(log, attr, empty)

    def _leave_out_impossible_times(self) -> None:
        log = self.log
        limit, deliver_limit = _time_bounds(log, self.scenario)
        log.end_utime, log.last_delivery_utime = limit, deliver_limit
        if "STATE" in self.keep:
            self._leave_out_impossible_states(limit)
        if "CHANNEL" in self.keep:
            self._leave_out_impossible_decisions(limit, deliver_limit)

    def _leave_out_impossible_states(self, limit: int) -> None:
        """analysis.cc ValidStates: a state is possible at 0 <= utime <= the run's end (any
        utime >= 0 when the end is unknown)."""
        log = self.log
        for vid, states in log.states.items():
            kept = []
            for st in states:
                if st.utime < 0:
                    log.states_negative_time += 1
                elif 0 <= limit < st.utime:
                    log.states_after_end += 1
                else:
                    kept.append(st)
                    continue
                log.damaged_states.append(st)
            log.states[vid] = kept
        if log.damaged_states:
            self.damaged_warnings.append(
                "DAMAGED: %d vehicle states at impossible times (%d negative, %d after the "
                "run's end at %.2f s), left out of the metrics"
                % (len(log.damaged_states), log.states_negative_time, log.states_after_end,
                   limit / 1e6 if limit >= 0 else float("nan")))

    def _leave_out_impossible_decisions(self, limit: int, deliver_limit: int) -> None:
        log = self.log
        kept: List[Decision] = []
        for d in log.decisions:
            why = _impossible(d, limit, deliver_limit)
            if not why:
                kept.append(d)
                continue
            log.damaged_decisions.append(d)
            if why == "sent":
                log.decisions_sent_impossible += 1
            else:
                log.decisions_delivered_impossible += 1
        log.decisions = kept
        if log.damaged_decisions:
            sent_end = deliver_end = ""
            if limit >= 0:  # without an end to judge by only the sign and order count
                sent_end = " or after %.2f s" % (limit / 1e6)
                deliver_end = " or after %.2f s" % (deliver_limit / 1e6)
            self.damaged_warnings.append(
                "DAMAGED: %d channel events at impossible times (%d sent at a negative "
                "time%s, %d delivered before sent%s), left out of the metrics"
                % (len(log.damaged_decisions), log.decisions_sent_impossible, sent_end,
                   log.decisions_delivered_impossible, deliver_end))


def _window_ok(count: int, max_s: float, bins: Optional[Tuple[int, ...]]) -> bool:
    """run_data.cc WindowOf: -1 (not reported), or bins >= 0 summing to the count and a
    finite maximum."""
    if count < 0:
        return count == -1
    return min(bins) >= 0 and sum(bins) == count and math.isfinite(max_s)


RETIMED_CHANNEL = "SHOAL-RETIMED"   # analysis/run_data.h kRetimedChannel
RETIMED_FORMAT = "shoal retimed log 1"


def _reject_constant(name):
    raise ValueError(name)


def _retimed_marker(data: bytes) -> Optional[Tuple[dict, List[str]]]:
    """run_data.cc ParseRetimedMarker: the marker `shoal retime` writes first (a JSON
    object), as analyze's JSON key retimed_from with the original's damage warnings, or
    None if it is not a valid marker."""
    try:
        j = json.loads(bytes(data).decode("utf-8-sig"), parse_constant=_reject_constant)
    except (ValueError, RecursionError):
        return None
    if not isinstance(j, dict) or j.get("format") != RETIMED_FORMAT:
        return None
    first, last = j.get("first_timestamp_us"), j.get("last_timestamp_us")
    source = j.get("source", "")
    if not isinstance(source, str):
        return None
    stamps = []
    for v in (first, last):
        if type(v) is not int or not -(1 << 63) <= v < (1 << 64):
            return None
        stamps.append(v - (1 << 64) if v > INT64_MAX else v)
    marker = {"log": source, "first_timestamp_us": stamps[0], "last_timestamp_us": stamps[1]}
    # The original's damage (run_data.cc LoadRunLog): a copy is as damaged as its original.
    damage = j.get("original_damage")
    marker_damage = [w for w in damage if isinstance(w, str)] if isinstance(damage, list) else []
    return marker, marker_damage


def _key_file_for(path: str, key_file: Optional[str]) -> Optional[str]:
    if key_file is not None:
        return key_file
    return path + ".key" if os.path.exists(path + ".key") else None


def _authenticate(log: ShoalLog, verifier: Optional[Verifier], kind: str, channel: str,
                  data: bytes) -> Optional[bytes]:
    """The message without its trailer, or None when it does not verify (counted)."""
    if not kind:
        return data  # not a Shoal channel: not read, not checked
    if verifier is None:
        n = trailer_bytes(data)
        if n:
            log.unverified += 1
            return data[:-n]
        return data
    payload = verifier.verify(channel, data)
    if payload is None:
        log.unauthenticated += 1
        by = log.unauthenticated_by_channel
        name = channel if len(by) < 256 or channel in by else "(other channels)"
        by[name] = by.get(name, 0) + 1
        return None
    log.verified += 1
    return payload


KINDS = ("STATE", "RX", "HEALTH", "CHANNEL", "CLOCK", "STATUS")


def read_log(path: str, key_file: Optional[str] = None, types_dir: Optional[str] = None,
             channels: Optional[Tuple[str, ...]] = None) -> ShoalLog:
    """Reads the Shoal log at `path`. key_file: the run's key (default: <path>.key if it
    exists; without one the messages are read unverified). types_dir: where the generated
    types are (load_types). channels: keep only these kinds ('STATE', 'RX', 'HEALTH',
    'CHANNEL', 'CLOCK', 'STATUS'; default all), the others are still verified and counted;
    the statuses and the states' ids are read whatever is kept (they give n and the ids that
    fit, as in a full read), STATE reads the clock too, and CHANNEL the states and the clock
    (they give the times a state or a decision can have). Raises ShoalLogError when the log cannot be read at all."""
    keep = KINDS if channels is None else tuple(channels)
    unknown = [k for k in keep if k not in KINDS]
    if unknown:
        raise ShoalLogError("channels: unknown kind %s (kinds: %s)"
                            % (", ".join(map(repr, unknown)), ", ".join(KINDS)))
    types = load_types(types_dir)
    log = ShoalLog(path=path, key_file=_key_file_for(path, key_file))
    verifier = Verifier(read_key_file(log.key_file)) if log.key_file else None
    reader = _EventReader(path)
    builder = _Builder(log, types, keep)
    original_damage: List[str] = []
    try:
        for timestamp, channel, data in reader:
            # A retimed log's marker is no event of the run (run_data.cc Add): the first
            # event, stamped with the first stamp it names; elsewhere a foreign event.
            if channel == RETIMED_CHANNEL and log.events == 0:
                parsed = _retimed_marker(data)
                if parsed is not None and parsed[0]["first_timestamp_us"] == timestamp:
                    log.retimed_from, original_damage = parsed
                    continue
            log.events += 1
            kind, cid = parse_channel(channel)
            payload = _authenticate(log, verifier, kind, channel, data)
            if payload is not None:
                builder.add(kind, cid, payload)
    finally:
        reader.close()
    builder.finish()
    log.warnings = (["the original log: " + w for w in original_damage] + reader.warnings +
                    builder.warnings + _authentication_warnings(log) +
                    _ignored_warnings(log) + builder.damaged_warnings)
    log.damaged = reader.damaged_regions > 0 or bool(original_damage)
    _check_usable(log, reader, builder.any_shoal)
    return log


def _authentication_warnings(log: ShoalLog) -> List[str]:
    w = []
    if log.unauthenticated:
        w.append("%d events did not authenticate with the run's key (forged, from another "
                 "run, or damaged) and were dropped" % log.unauthenticated)
    if log.unverified:
        w.append("%d events carry an authentication trailer that could not be checked (no "
                 "key: give --key FILE, or keep <log>.key next to the log); they were read "
                 "unverified" % log.unverified)
    if log.insecure_run:
        w.append("the run's bus was not authenticated (--insecure): anyone on the host could "
                 "have published into it")
    return w


def _ignored_warnings(log: ShoalLog) -> List[str]:
    """run_data.cc NoteIgnored."""
    w = []
    if log.undecodable:
        w.append("%d messages on Shoal channels did not decode (wrong size or fingerprint, a "
                 "damaged string length) and were ignored" % log.undecodable)
    if log.rejected:
        w.append("%d messages were inconsistent (a vehicle id that does not match its channel "
                 "or lies beyond the scenario's followers, a health window that does not add "
                 "up) and were ignored" % log.rejected)
    return w


def _check_usable(log: ShoalLog, reader: _EventReader, any_shoal: bool) -> None:
    """run_data.cc LoadRunLog: a log of events none of which is a valid Shoal message (a
    state, a channel decision, a health report, a clock message or a status) is refused."""
    if log.events == 0:
        raise ShoalLogError(log.path + ": no complete LCM event in the file" +
                            (" (" + reader.warnings[0] + ")" if reader.warnings else ""))
    if not any_shoal and log.unauthenticated:
        raise ShoalLogError("%s: none of its %d events authenticates with the key in %s (the "
                            "log of another run, or of a run with --insecure?)"
                            % (log.path, log.events, log.key_file))
    if not any_shoal:
        raise ShoalLogError("%s: an LCM log with %d events but no Shoal message (no valid "
                            "SHOAL_* channel)" % (log.path, log.events))


# ------------------------------------------------------------------------- pandas

# The state columns of shoal analyze --csv's vehicle_<id>.csv (docs/analyze.md).
STATE_COLUMNS = (
    ["x_m", "y_m", "z_m", "theta_rad", "psi_rad"],
    ["u_mps", "v_mps", "w_mps", "q_radps", "r_radps"],
    ["x_dot_mps", "y_dot_mps", "z_dot_mps", "theta_dot_radps", "psi_dot_radps"],
    ["accel_x_mps2", "accel_y_mps2", "accel_z_mps2", "accel_theta_radps2", "accel_psi_radps2"],
    ["tau_x_n", "tau_y_n", "tau_z_n", "tau_m_nm", "tau_n_nm"])


def _state_row(s: State) -> dict:
    row = {"vehicle": s.vehicle_id, "time_s": s.utime / 1e6, "utime_us": s.utime, "seq": s.seq}
    for names, values in zip(STATE_COLUMNS, (s.eta, s.nu, s.eta_dot, s.accel_cmd, s.tau)):
        row.update(zip(names, values))
    row["flags"] = s.flags
    return row


def frames(log: ShoalLog) -> dict:
    """pandas DataFrames of a log (pandas is optional: Debian's python3-pandas):
    'states' (one row per state, the columns of shoal analyze --csv's vehicle_<id>.csv
    plus vehicle and flags), 'decisions', 'clock', 'health' (without the histogram bins),
    'statuses'. Raises ShoalLogError if pandas is not installed."""
    try:
        import pandas
    except ImportError:
        raise ShoalLogError("pandas is not installed (Debian: apt install python3-pandas); "
                            "the records need no pandas: ShoalLog.states, .decisions, ...") \
            from None
    state_columns = ["vehicle", "time_s", "utime_us", "seq"] + \
        [c for names in STATE_COLUMNS for c in names] + ["flags"]

    def table(records, cls, leave_out=()):
        names = [f.name for f in dataclasses.fields(cls) if f.name not in leave_out]
        return pandas.DataFrame([[getattr(r, n) for n in names] for r in records],
                                columns=names)

    return {
        "states": pandas.DataFrame([_state_row(s) for states in log.states.values()
                                    for s in states], columns=state_columns),
        "decisions": table(log.decisions, Decision),
        "clock": table(log.clock, Clock),
        "health": table([h for reports in log.health.values() for h in reports], Health,
                        ("lateness_window_bins",)),
        "statuses": table(log.statuses, Status),
    }


# ----------------------------------------------------------------------- the summary

def summary(log: ShoalLog) -> dict:
    """What the CLI prints: plain data (JSON-ready)."""
    vehicles = []
    for vid, states in log.states.items():
        vehicles.append({"id": vid, "states": len(states),
                         "first_s": states[0].utime / 1e6 if states else None,
                         "last_s": states[-1].utime / 1e6 if states else None,
                         "final_position_m": list(states[-1].eta[:3]) if states else None})
    health = {}
    for pid, reports in log.health.items():
        # The newest in mission time (of two at one time, the later in the log), as shoal
        # analyze takes it: a report replayed later in the log must not hide what came after.
        last = reports[0]
        for h in reports:
            if h.utime >= last.utime:
                last = h
        health[str(pid)] = {"reports": len(reports), "ticks": last.ticks,
                            "lateness_p99_s": last.lateness_p99_s, "overruns": last.overruns,
                            "msgs_received": last.msgs_received,
                            "msgs_dropped_invalid": last.msgs_dropped_invalid}
    names = [s.scenario_name for s in log.statuses if s.scenario_name]
    return {
        "log": log.path, "scenario": names[0] if names else None, "followers": log.followers,
        "retimed_from": log.retimed_from, "events": log.events,
        "states": sum(len(s) for s in log.states.values()),
        "states_damaged": len(log.damaged_states),
        "states_negative_time": log.states_negative_time,
        "states_after_end": log.states_after_end,
        "vehicles": vehicles, "decisions": log.decision_counts(),
        "decisions_damaged": len(log.damaged_decisions),
        "decisions_sent_at_impossible_time": log.decisions_sent_impossible,
        "decisions_delivered_at_impossible_time": log.decisions_delivered_impossible,
        "clock_messages": len(log.clock), "clock_ticks": log.clock_ticks(),
        "rx_messages": {str(k): v for k, v in sorted(log.rx.items())},
        "health": health, "statuses": [[s.vehicle_id, s.state] for s in log.statuses],
        "authentication": {
            "key_file": log.key_file, "verified": log.verified,
            "unauthenticated": log.unauthenticated,
            "unauthenticated_by_channel": dict(sorted(log.unauthenticated_by_channel.items())),
            "unverified": log.unverified, "insecure_run": log.insecure_run},
        "undecodable": log.undecodable, "rejected": log.rejected,
        "repeated_states": log.repeated_states,
        "repeated_decisions": log.repeated_decisions, "repeated_health": log.repeated_health,
        "damaged": log.damaged,
        "warnings": log.warnings,
    }


def _auth_line(s: dict) -> str:
    a = s["authentication"]
    if a["key_file"] is None:
        text = "authentication: no key (no <log>.key, no --key): messages NOT verified"
        if a["unverified"]:
            text += " (%d carry a trailer, stripped unchecked)" % a["unverified"]
        return text
    text = "authentication: key %s, %d messages verified, %d did not verify (dropped)" % (
        a["key_file"], a["verified"], a["unauthenticated"])
    if a["unauthenticated_by_channel"]:
        text += ": " + ", ".join("%s %d" % kv for kv in a["unauthenticated_by_channel"].items())
    return text


def format_summary(s: dict) -> str:
    d = s["decisions"]
    lines = ["%s: scenario %s, %d followers, %d events" % (s["log"], s["scenario"],
                                                          s["followers"], s["events"]),
             _auth_line(s),
             "states: %d" % s["states"]]
    if s["retimed_from"] is not None:
        lines.insert(1, "RETIMED log (event times in mission time) of %s; the wall time is the "
                     "original recording's" % s["retimed_from"]["log"])
    for v in s["vehicles"]:
        span = "no state" if v["first_s"] is None else "%.3f..%.3f s" % (v["first_s"],
                                                                        v["last_s"])
        lines.append("  vehicle %d%s: %d states, %s" % (
            v["id"], " (leader)" if v["id"] == 0 else "", v["states"], span))
    lines.append("channel decisions: %d sent, %d delivered, %d dropped (loss %d, queue %d, "
                 "range %d, link down %d, deaf %d, invalid %d); not sent: modem busy %d, "
                 "silent %d" % (d["sent"], d["delivered"], d["dropped"], d["dropped_loss"],
                                d["dropped_queue"], d["dropped_range"], d["dropped_link_down"],
                                d["dropped_deaf"], d["dropped_invalid"],
                                d["skipped_modem_busy"], d["skipped_silent"]))
    lines.append("clock: %d messages, %d ticks" % (s["clock_messages"], s["clock_ticks"]))
    for pid, h in s["health"].items():
        lines.append("  health %s: %d reports, last: %d ticks, lateness p99 %.6f s, %d "
                     "overruns, %d received, %d dropped invalid" % (
                         pid, h["reports"], h["ticks"], h["lateness_p99_s"], h["overruns"],
                         h["msgs_received"], h["msgs_dropped_invalid"]))
    lines.append("statuses: " + ", ".join("%d %s" % (i, st) for i, st in s["statuses"]))
    if s["undecodable"] or s["rejected"]:
        lines.append("undecodable %d, rejected %d" % (s["undecodable"], s["rejected"]))
    lines += ["warning: " + w for w in s["warnings"]]
    return "\n".join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="shoal_log.py", description="Summarises a Shoal LCM log (docs/analyze.md, "
        "\"Reading a log from Python\"). Exit status 0 read (a damaged log too: warnings), "
        "2 the log, the key or the generated types cannot be read.")
    p.add_argument("log", help="the LCM log (shoal sim --out, shoal run --out, lcm-logger)")
    p.add_argument("--key", metavar="FILE", help="the run's key file (default: LOG.key if "
                   "it exists; without a key the messages are not verified)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--types", metavar="DIR", help="the directory that holds the generated "
                   "package shoal/ (default: $" + TYPES_ENV + ", this file's directory, "
                   "../build/python)")
    args = p.parse_args(argv)
    try:
        log = read_log(args.log, key_file=args.key, types_dir=args.types)
    except ShoalLogError as e:
        print("shoal_log.py: " + str(e), file=sys.stderr)
        return 2
    s = summary(log)
    try:
        print(json.dumps(_strict(s), indent=1) if args.json else format_summary(s), flush=True)
    except BrokenPipeError:  # e.g. | head: the reader has gone, nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    for w in log.warnings:
        print("shoal_log.py: warning: " + w, file=sys.stderr)
    return 0


def _strict(x):
    """JSON without NaN or Infinity (a diverging vehicle's state): null, as shoal analyze."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_strict(v) for v in x]
    return x


if __name__ == "__main__":
    sys.exit(main())
