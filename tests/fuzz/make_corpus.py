#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpora (tests/fuzz/corpus/<target>/) from real data.

  tests/fuzz/make_corpus.py BUILD_DIR

fuzz_decode:     messages of a `shoal sim --out` log, one file per message, prefixed with
                 the byte that selects its type in fuzz_decode.cc; clock_window_t and
                 channel_event_t (not logged) built from the logged clock ticks and
                 channel decisions; health_t (older logs) cut from the logged
                 health2_t (its leading fields).
fuzz_log_reader: the log's first events, whole and cut short.
fuzz_scenario:   scenarios/*.toml and tests/data/bad_scenarios/*.toml.
fuzz_campaign:   campaigns/*.toml and tests/data/campaigns/*.toml.
Small on purpose (the fuzzer grows its own corpus in a work directory, bench/fuzz.sh).
"""
import pathlib
import re
import shutil
import struct
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests" / "fuzz" / "corpus"
# fuzz_decode.cc's type selector (first byte).
SELECT = {"vehicle_state_t": 0, "clock_window_t": 1, "clock_tick_t": 2,
          "channel_events_t": 3, "health_t": 4, "health2_t": 4, "run_status_t": 5,
          "channel_event_t": 6}
SYNC = 0xEDA1DA01
PER_TYPE = 3   # messages kept per type
LOG_EVENTS = 40


def read_events(path):
    data = path.read_bytes()
    pos, events = 0, []
    while pos + 28 <= len(data):
        sync, _, _, clen, dlen = struct.unpack_from(">IqqII", data, pos)
        assert sync == SYNC, f"{path}: bad sync at {pos}"
        end = pos + 28 + clen + dlen
        channel = data[pos + 28:pos + 28 + clen].decode()
        events.append((channel, data[pos + 28 + clen:end], data[pos:end]))
        pos = end
    return events


def type_of(channel):
    if channel.startswith("SHOAL_STATE_"):
        return "vehicle_state_t"
    return {"SHOAL_CLOCK": "clock_tick_t", "SHOAL_CHANNEL": "channel_events_t",
            "SHOAL_STATUS": "run_status_t"}.get(channel,
            "health2_t" if channel.startswith("SHOAL_HEALTH_") else None)


def hash_of(build, name):
    """getHash() of a type without nested types (lcm-gen: the constant, rotated left by 1)."""
    text = (build / "lcmtypes" / "include" / "shoal" / f"{name}.hpp").read_text()
    h = int(re.search(r"uint64_t hash = 0x([0-9a-fA-F]+)LL;", text).group(1), 16)
    return ((h << 1) | (h >> 63)) & (2**64 - 1)


def clock_windows(build, ticks):
    """clock_window_t built from clock_tick_t fields (first without, then with a delivery)."""
    out = []
    for k, tick in enumerate(ticks[:2]):
        _, utime, vid, seq, tk, period, final, n = struct.unpack_from(">QqiiqqbI", tick)
        body = struct.pack(">qiiqiqb", utime, vid, seq, tk, 1, period, final)
        body += struct.pack(">i", k) + (struct.pack(">qiiiq", tk, 1, 0, seq, 12345) if k else b"")
        out.append(struct.pack(">Q", hash_of(build, "clock_window_t")) + body)
    return out


def channel_events(build, batches):
    """channel_event_t: the first decision of logged channel_events_t batches."""
    out = []
    for batch in batches:
        (n,) = struct.unpack_from(">i", batch, 24)
        if n < 1:
            continue
        start = 28
        (rlen,) = struct.unpack_from(">i", batch, start + 8 + 4 * 5 + 8 * 3 + 1)
        end = start + 8 + 4 * 5 + 8 * 3 + 1 + 4 + rlen
        out.append(struct.pack(">Q", hash_of(build, "channel_event_t")) + batch[start:end])
    return out


def old_health(build, reports):
    """health_t: health2_t without its window (count, max, 162 bins), under health_t's hash."""
    window = 8 + 8 + 162 * 4
    return [struct.pack(">Q", hash_of(build, "health_t")) + r[8:len(r) - window]
            for r in reports]


def write(target, name, data):
    d = CORPUS / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data)


def main():
    build = pathlib.Path(sys.argv[1]).resolve()
    for target in ("fuzz_decode", "fuzz_log_reader", "fuzz_scenario", "fuzz_campaign"):
        shutil.rmtree(CORPUS / target, ignore_errors=True)
    with tempfile.TemporaryDirectory() as tmp:
        log = pathlib.Path(tmp) / "sim.lcmlog"
        subprocess.run([str(build / "tools" / "shoal"), "sim",
                        str(ROOT / "scenarios" / "paper_example1.toml"), "--out", str(log)],
                       check=True, stdout=subprocess.DEVNULL)
        events = read_events(log)
    by_type = {}
    for channel, data, _ in events:
        t = type_of(channel)
        if t:
            by_type.setdefault(t, []).append(data)
    by_type["clock_window_t"] = clock_windows(build, by_type.get("clock_tick_t", []))
    by_type["channel_event_t"] = channel_events(build, by_type.get("channel_events_t", []))
    by_type["health_t"] = old_health(build, by_type.get("health2_t", []))
    for t, msgs in sorted(by_type.items()):
        for k, m in enumerate(msgs[:PER_TYPE]):
            write("fuzz_decode", f"{t}_{k}", bytes([SELECT[t]]) + m)
    # The log's start (its status carries the scenario text) and the same cut mid-event.
    head = b"".join(raw for _, _, raw in events[:LOG_EVENTS])
    write("fuzz_log_reader", "sim_head", head)
    write("fuzz_log_reader", "sim_head_cut", head[:len(head) - 50])
    for src in sorted((ROOT / "scenarios").glob("*.toml")) + \
            sorted((ROOT / "tests" / "data" / "bad_scenarios").glob("*.toml")):
        write("fuzz_scenario", src.name, src.read_bytes())
    for src in sorted((ROOT / "campaigns").glob("*.toml")) + \
            sorted((ROOT / "tests" / "data" / "campaigns").glob("*.toml")):
        write("fuzz_campaign", src.name, src.read_bytes())


if __name__ == "__main__":
    main()
