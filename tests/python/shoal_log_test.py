#!/usr/bin/env python3
"""python/shoal_log.py against shoal analyze, on the logs of a real lockstep run and of
shoal sim: the same states per vehicle, channel decisions, clock ticks and authentication
counts, the final formation position error recomputed from the states, one altered
message refused by both, damaged logs read without a traceback: messages that do not
decode or name ids that do not fit, decisions at impossible times, a retimed log, more
damaged places than are listed, the same warnings.

The script tested is the source tree's python/shoal_log.py (the build's copy in
build/python/ is that file once the build has run), with the types of build/python/.

Usage (ctest runs it, tests/python/CMakeLists.txt): shoal_log_test.py BUILD_DIR SOURCE_DIR
"""

import json
import math
import os
import random
import re
import shutil
import struct
import subprocess
import sys
import unittest

BUILD, SOURCE = (os.path.abspath(a) for a in sys.argv[1:3])
PYDIR = os.path.join(BUILD, "python")
SHOAL = os.path.join(BUILD, "tools", "shoal")
TMP = os.path.join(BUILD, "test_tmp", "shoal_log_test")
EXAMPLE2 = os.path.join(SOURCE, "scenarios", "paper_example2.toml")
FAULTS = os.path.join(SOURCE, "scenarios", "faults.toml")

SCRIPT = os.path.join(SOURCE, "python", "shoal_log.py")
sys.dont_write_bytecode = True  # nothing written into the source tree
os.environ["SHOAL_PYTHON_TYPES"] = PYDIR  # the build's types, for the source tree's script
sys.path.insert(0, os.path.dirname(SCRIPT))
import shoal_log  # noqa: E402

try:
    import pandas  # optional (Debian: python3-pandas): shoal_log.frames
except ImportError:
    pandas = None

try:
    import tomllib  # Python 3.11+; the offsets of older Pythons come from a fixed table
except ImportError:
    tomllib = None


def run(args, ok=(0,), env=None):
    p = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=240, env=None if env is None else dict(os.environ, **env))
    if p.returncode not in ok:
        raise AssertionError("%s: exit %d\n%s\n%s" % (args, p.returncode, p.stdout, p.stderr))
    return p


def analyze(log, *extra):
    return json.loads(run([SHOAL, "analyze", log, "--json", *extra]).stdout)


def analyze_refuses(log, *extra):
    """shoal analyze's message for a log it cannot analyse (exit status 2)."""
    return run([SHOAL, "analyze", log, *extra], ok=(2,)).stderr


def offsets_of(log):
    """The scenario's formation offsets d_i, from the scenario text in the log."""
    if tomllib is not None:
        return tomllib.loads(log.scenario_toml)["control"]["offsets_m"]
    return [[6.0, 6.0, 0.0], [6.0, -6.0, 0.0], [-6.0, 6.0, 0.0], [-6.0, -6.0, 0.0],
            [0.0, 0.0, 5.0]]  # paper_example2.toml and faults.toml


def final_position_errors(log):
    """Per follower i, ||(p_i - d_i) - p_0|| at the last complete sample: the last time at
    which the leader and every follower have a state (docs/analyze.md, Metrics:
    followers[].final_* are taken there, as shoal sim's)."""
    times = set.intersection(*({s.utime for s in states} for states in log.states.values()))
    last = max(times)
    at = {v: next(s for s in states if s.utime == last) for v, states in log.states.items()}
    out = {}
    for i, d in enumerate(offsets_of(log), start=1):
        e = [(at[i].eta[k] - d[k]) - at[0].eta[k] for k in range(3)]
        out[i] = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    return out


def read_events(path):
    """[channel, data, timestamp] of every event of a clean log."""
    with open(path, "rb") as f:
        b = f.read()
    out, pos = [], 0
    while pos < len(b):
        ts = int.from_bytes(b[pos + 12:pos + 20], "big", signed=True)
        cl = int.from_bytes(b[pos + 20:pos + 24], "big")
        dl = int.from_bytes(b[pos + 24:pos + 28], "big")
        data = bytearray(b[pos + 28 + cl:pos + 28 + cl + dl])
        out.append([b[pos + 28:pos + 28 + cl].decode(), data, ts])
        pos += 28 + cl + dl
    return out


def write_events(path, events):
    with open(path, "wb") as f:
        for k, (channel, data, ts) in enumerate(events):
            c = channel.encode()
            f.write(struct.pack(">Iqqii", 0xEDA1DA01, k, ts, len(c), len(data)) + c + bytes(data))


def i32(data, at, value=None):
    """The big-endian int32 at `at` of data, after setting it to value if given."""
    if value is not None:
        data[at:at + 4] = struct.pack(">i", value)
    return struct.unpack_from(">i", data, at)[0]


# channel_events_t: hash, utime, vehicle_id, seq, n_events, then each event: utime,
# vehicle_id, seq, sender (+16), receiver (+20), msg_seq, send_utime (+28), delay_s,
# deliver_utime (+44), status (+52), the reason's length (+53) and bytes (NUL included).
def batch_events(data):
    """The offsets of a channel_events_t batch's events in data."""
    out, at = [], 28
    for _ in range(i32(data, 24)):
        out.append(at)
        at += 57 + i32(data, at + 53)
    return out


def status_strings(data):
    """The offsets of a run_status_t's string lengths: state, scenario_name, scenario_toml,
    message."""
    out, at = [], 24
    for k in range(4):
        out.append(at)
        at += 4 + i32(data, at) + (12 if k == 2 else 0)
    return out


def event_offsets(path):
    """(offset, channel, data offset, data length) of every event of a clean log."""
    with open(path, "rb") as f:
        b = f.read()
    out, pos = [], 0
    while pos < len(b):
        cl = int.from_bytes(b[pos + 20:pos + 24], "big")
        dl = int.from_bytes(b[pos + 24:pos + 28], "big")
        out.append((pos, b[pos + 28:pos + 28 + cl].decode(), pos + 28 + cl, dl))
        pos += 28 + cl + dl
    return out


class Logs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        shutil.rmtree(TMP, ignore_errors=True)
        os.makedirs(TMP)
        cls.run_log = os.path.join(TMP, "lockstep.lcmlog")
        cls.sim_log = os.path.join(TMP, "sim.lcmlog")
        # A real lockstep run: its own processes on a private bus (shoal run's random
        # port), authenticated, with message loss so that some decisions are drops.
        run([SHOAL, "run", EXAMPLE2, "--mode", "lockstep", "--duration", "10", "--quiet",
             "--set", 'channel.loss={ model = "bernoulli", probability = 0.1 }',
             "--out", cls.run_log], ok=(0, 1))
        # Every status of the channel and the timeline's events (link down, silent, deaf):
        # scenarios/faults.toml at a tenth of its times (40 s; its log is 10 MB, not 100).
        with open(FAULTS) as f:
            text = f.read()
        text = re.sub(r"(?m)^(duration_s|at_s|until_s) = ([0-9]+)",
                      lambda m: "%s = %g" % (m.group(1), int(m.group(2)) / 10), text)
        scenario = os.path.join(TMP, "faults_short.toml")
        with open(scenario, "w") as f:
            f.write(text)
        run([SHOAL, "sim", scenario, "--out", cls.sim_log], ok=(0, 1))

    def check_against_analyze(self, log, a):
        """The figures both compute from the same log."""
        self.assertEqual(log.events, a["log_events"])
        n = len(a["followers"])
        self.assertEqual(log.followers, n)
        self.assertEqual(sum(len(s) for s in log.states.values()), a["log_states"])
        for f in a["followers"]:
            self.assertEqual(len(log.states[f["id"]]), f["samples"], f["id"])
        self.assertEqual(len(log.states[0]),
                         a["log_states"] - sum(f["samples"] for f in a["followers"]))
        counts = log.decision_counts()
        for key in ("sent", "delivered", "dropped", "dropped_loss", "dropped_queue",
                    "dropped_invalid", "dropped_range", "skipped_modem_busy",
                    "skipped_silent", "dropped_link_down", "dropped_deaf"):
            self.assertEqual(counts[key], a["channel"][key], key)
        self.assertEqual(counts["delivered"], a["channel_delivered"])
        self.assertEqual(counts["dropped"], a["channel_dropped"])
        self.assertEqual(log.clock_ticks(), a["ticks"])
        for key in ("verified", "unauthenticated", "unverified", "unauthenticated_by_channel"):
            self.assertEqual(getattr(log, key), a["authentication"][key], key)
        self.assertEqual(log.undecodable, a["log_undecodable"])
        self.assertEqual(log.rejected, a["log_rejected"])
        self.assertEqual(len(log.damaged_decisions), a["channel_events_damaged"])
        self.assertEqual(log.decisions_sent_impossible,
                         a["channel_events_sent_at_impossible_time"])
        self.assertEqual(log.decisions_delivered_impossible,
                         a["channel_events_delivered_at_impossible_time"])
        if tomllib is not None:  # without it the logged scenario's end is not read
            for mine, theirs in ((log.end_utime, a["log_end_s"]),
                                 (log.last_delivery_utime, a["log_last_delivery_s"])):
                self.assertEqual(mine, -1 if theirs is None else round(theirs * 1e6))
        self.assertEqual(log.retimed_from, a["retimed_from"])
        self.assertEqual({k: len(v) for k, v in log.health.items()},
                         {p["id"]: p["reports"] for p in a["loop"]["processes"]})
        # The same warnings, but analyze's about the missing scenario (formation errors,
        # which Python does not compute) and Python's DAMAGED line (analyze prints it in its
        # report, not as a warning).
        self.assertEqual([w for w in log.warnings if not w.startswith("DAMAGED: ")],
                         [w for w in a["warnings"] if not w.startswith("no scenario text")])
        errors = final_position_errors(log)
        for f in a["followers"]:
            self.assertAlmostEqual(errors[f["id"]], f["final_position_error_m"], delta=1e-9)
        self.assertAlmostEqual(max(errors.values()), a["final_position_error_m"], delta=1e-9)

    def test_lockstep_run_equals_shoal_analyze(self):
        log = shoal_log.read_log(self.run_log)
        a = analyze(self.run_log)
        self.assertEqual(log.key_file, self.run_log + ".key")
        self.assertEqual(a["mode"], "lockstep")
        self.assertTrue(a["bus_authenticated"])
        self.assertGreater(log.verified, 1000)
        self.assertEqual(log.unauthenticated, 0)
        self.assertEqual(len(log.states), 6)
        self.assertEqual(len(log.states[3]), 501)  # 10 s at 50 Hz, ticks 0..500
        self.assertGreater(log.decision_counts()["dropped_loss"], 100)
        self.assertEqual(log.warnings, [])
        self.check_against_analyze(log, a)

    def test_sim_log_equals_shoal_analyze(self):
        log = shoal_log.read_log(self.sim_log)
        a = analyze(self.sim_log)
        self.assertIsNone(log.key_file)
        self.assertEqual(log.unverified, 0)  # shoal sim has no bus: no trailers
        c = log.decision_counts()
        for key in ("dropped_link_down", "skipped_silent", "dropped_deaf", "dropped_loss"):
            self.assertGreater(c[key], 0, key)
        self.assertEqual(len(log.states[0]), 2001)  # 40 s at 50 Hz, ticks 0..2000
        self.check_against_analyze(log, a)
        self.assertEqual({s.state for s in log.statuses} >= {"running", "finished"}, True)
        only = shoal_log.read_log(self.sim_log, channels=("STATE",))
        self.assertEqual(only.states, log.states)
        self.assertEqual((only.decisions, only.clock, only.health), ([], [], {}))
        self.assertEqual(only.events, log.events)

    def test_without_the_key_messages_are_unverified(self):
        bare = os.path.join(TMP, "nokey.lcmlog")
        shutil.copyfile(self.run_log, bare)
        log = shoal_log.read_log(bare)
        a = analyze(bare)
        self.assertIsNone(log.key_file)
        self.assertGreater(log.unverified, 1000)
        self.assertEqual(log.unverified, a["authentication"]["unverified"])
        self.assertEqual(log.verified, 0)
        self.check_against_analyze(log, a)
        p = run([sys.executable, SCRIPT, bare])
        self.assertIn("NOT verified", p.stdout)

    def test_an_altered_message_does_not_verify(self):
        events = event_offsets(self.run_log)
        states2 = [e for e in events if e[1] == "SHOAL_STATE_2"]
        _, channel, data_at, _ = states2[len(states2) // 2]
        forged = os.path.join(TMP, "forged.lcmlog")
        with open(self.run_log, "rb") as f:
            b = bytearray(f.read())
        b[data_at + 40] ^= 0x01  # a bit of its x position
        with open(forged, "wb") as f:
            f.write(b)
        shutil.copyfile(self.run_log + ".key", forged + ".key")
        log = shoal_log.read_log(forged)
        a = analyze(forged)
        self.assertEqual(log.unauthenticated, 1)
        self.assertEqual(log.unauthenticated_by_channel, {channel: 1})
        self.assertEqual(a["authentication"]["unauthenticated"], 1)
        self.assertEqual(len(log.states[2]), len(shoal_log.read_log(self.run_log).states[2]) - 1)
        self.check_against_analyze(log, a)
        p = run([sys.executable, SCRIPT, forged])
        self.assertIn("1 did not verify (dropped): SHOAL_STATE_2 1", p.stdout)

    def test_siphash_in_python_verifies_the_run_as_libsodium_does(self):
        fast = shoal_log.siphash128
        try:
            shoal_log.siphash128 = shoal_log.siphash128_python
            log = shoal_log.read_log(self.run_log)
        finally:
            shoal_log.siphash128 = fast
        want = shoal_log.read_log(self.run_log)
        self.assertGreater(log.verified, 0)
        self.assertEqual((log.verified, log.unauthenticated), (want.verified, 0))

    def test_a_message_longer_than_its_type_does_not_decode(self):
        # The generated decoder reads what the fields ask for and ignores the rest: a state
        # with one byte more must be refused (shoal analyze's decoder needs every byte used).
        events = event_offsets(self.sim_log)
        at, _, data_at, size = [e for e in events if e[1] == "SHOAL_STATE_1"][100]
        with open(self.sim_log, "rb") as f:
            b = bytearray(f.read())
        b[at + 24:at + 28] = (size + 1).to_bytes(4, "big")
        b[data_at + size:data_at + size] = b"\0"
        longer = os.path.join(TMP, "longer.lcmlog")
        with open(longer, "wb") as f:
            f.write(b)
        log = shoal_log.read_log(longer)
        self.assertEqual(log.undecodable, 1)
        self.assertEqual(len(log.states[1]), len(shoal_log.read_log(self.sim_log).states[1]) - 1)
        self.check_against_analyze(log, analyze(longer))

    @unittest.skipIf(pandas is None, "pandas is not installed (Debian: python3-pandas)")
    def test_frames_equal_shoal_analyze_csv(self):
        log = shoal_log.read_log(self.sim_log)
        f = shoal_log.frames(log)
        csv_dir = os.path.join(TMP, "csv")
        run([SHOAL, "analyze", self.sim_log, "--csv", csv_dir])
        states = f["states"]
        self.assertEqual(states.groupby("vehicle").size().to_dict(),
                         {v: len(s) for v, s in log.states.items()})
        d = log.decision_counts()
        self.assertEqual(f["decisions"].status_name.value_counts().to_dict(),
                         {k: v for k, v in d.items() if v and k not in ("sent", "dropped")})
        self.assertEqual(len(f["clock"]), len(log.clock))
        self.assertEqual(len(f["health"]), sum(len(h) for h in log.health.values()))
        self.assertEqual(list(f["statuses"].state), [s.state for s in log.statuses])
        offsets = offsets_of(log)
        lead = states[states.vehicle == 0].set_index("utime_us")
        for i in (1, 4):
            # The CSV holds the logged doubles in their shortest exact form: bit for bit
            # when read back exactly (pandas 1.5's default parser can be 1 ulp off).
            csv = pandas.read_csv(os.path.join(csv_dir, "vehicle_%d.csv" % i),
                                  float_precision="round_trip")
            mine = states[states.vehicle == i].reset_index(drop=True)
            for column in csv.columns.intersection(mine.columns):
                self.assertTrue((csv[column] == mine[column]).all(), column)
            fol = mine.set_index("utime_us")
            e = sum(((fol[c] - offsets[i - 1][k]) - lead[c]) ** 2
                    for k, c in enumerate(("x_m", "y_m", "z_m"))) ** 0.5
            diff = (e.reset_index(drop=True) - csv.position_error_m).abs().max()
            self.assertLess(diff, 1e-9, i)
        with self.assertRaisesRegex(shoal_log.ShoalLogError, "pandas is not installed"):
            saved, sys.modules["pandas"] = sys.modules.get("pandas"), None
            try:
                shoal_log.frames(log)
            finally:
                sys.modules["pandas"] = saved

    def test_another_runs_key_verifies_nothing(self):
        other = os.path.join(TMP, "other.key")
        with open(other, "w") as f:
            f.write("ab" * 32 + "\n")
        with self.assertRaisesRegex(shoal_log.ShoalLogError, "none of its .* authenticates"):
            shoal_log.read_log(self.run_log, key_file=other)
        self.assertIn("authenticates with the key", analyze_refuses(self.run_log, "--key", other))
        p = run([sys.executable, SCRIPT, self.run_log, "--key",
                 other], ok=(2,))
        self.assertNotIn("Traceback", p.stderr)

    def damaged(self, name, edit):
        with open(self.run_log, "rb") as f:
            b = bytearray(f.read())
        edit(b)
        path = os.path.join(TMP, name)
        with open(path, "wb") as f:
            f.write(b)
        shutil.copyfile(self.run_log + ".key", path + ".key")
        return path

    def test_damaged_logs_are_read_as_shoal_analyze_reads_them(self):
        events = event_offsets(self.run_log)
        middle = events[len(events) // 2]
        cut = self.damaged("truncated.lcmlog", lambda b: b.__delitem__(
            slice(events[-5][2] + 3, None)))
        bad_sync = self.damaged("bad_sync.lcmlog", lambda b: b.__setitem__(middle[0], 0))
        bad_len = self.damaged("bad_length.lcmlog", lambda b: b.__setitem__(
            slice(middle[0] + 24, middle[0] + 28), (5000).to_bytes(4, "big")))
        for path, words in ((cut, "truncated"), (bad_sync, "no sync word"),
                            (bad_len, "lengths do not lead")):
            log = shoal_log.read_log(path)
            a = analyze(path)
            self.assertTrue(log.damaged)
            self.assertEqual(len(log.warnings), 1, log.warnings)
            self.assertIn(words, log.warnings[0])
            self.assertEqual([w for w in a["warnings"] if "byte" in w], log.warnings)
            self.check_against_analyze(log, a)
            p = run([sys.executable, SCRIPT, path])
            self.assertIn("warning: ", p.stdout)
            self.assertNotIn("Traceback", p.stderr)
        self.assertEqual(shoal_log.read_log(bad_sync).events, len(events) - 1)

    def test_random_damage_is_read_as_shoal_analyze_reads_it(self):
        # Bytes changed or cut at random places (a fixed seed): the two readers find the
        # same events, states, decisions, authentication failures and warnings.
        rng = random.Random(7)
        with open(self.run_log, "rb") as f:
            original = f.read()
        for case in range(24):
            b = bytearray(original)
            for _ in range(rng.randint(1, 4)):
                at = rng.randrange(len(b))
                b[at:at + 4] = bytes(rng.randrange(256) for _ in range(4))
            if case % 3 == 0:
                del b[rng.randrange(len(b) // 2, len(b)):]
            path = self.damaged("random_%d.lcmlog" % case, lambda x: x.__setitem__(
                slice(None), b))  # b, with the run's key beside it
            log = shoal_log.read_log(path)
            a = analyze(path)
            self.assertEqual([w for w in a["warnings"] if "byte" in w],
                             [w for w in log.warnings if "byte" in w], case)
            self.check_against_analyze(log, a)

    def edited_sim(self, name, edit):
        """The shoal sim log (no trailers, no key) with its events edited in place:
        edit(events), events as read_events gives them."""
        events = read_events(self.sim_log)
        edit(events)
        path = os.path.join(TMP, name)
        write_events(path, events)
        return path

    def test_strings_that_do_not_fit_do_not_decode(self):
        # The generated decoder reads a string's length from the message and that many bytes
        # from a buffer: a length past the end reads short unnoticed, and the last byte is
        # dropped unseen. shoal analyze refuses both, and a length of 0.
        def last_status(events):
            return [e for e in events if e[0] == "SHOAL_STATUS"][-1][1]

        def message_longer(events):
            data = last_status(events)
            at = status_strings(data)[3]
            i32(data, at, i32(data, at) + 10)  # 10 bytes past the message's end

        def no_nul(events):
            last_status(events)[-1:] = b"X"  # the message's closing NUL

        def reason_length_0(events):
            for _, data, _ in events[len(events) // 2:]:
                if data[:8] != events_hash or not batch_events(data):
                    continue
                at = batch_events(data)[-1] + 53
                if i32(data, at) == 1:  # reason "": its length 0 and no NUL
                    i32(data, at, 0)
                    del data[at + 4]
                    return
            self.fail("no batch ends with an empty reason")

        events_hash = next(e[1][:8] for e in read_events(self.sim_log)
                           if e[0] == "SHOAL_CHANNEL")
        clean = shoal_log.read_log(self.sim_log)
        for name, edit in (("message_longer", message_longer), ("no_nul", no_nul),
                           ("reason_length_0", reason_length_0)):
            path = self.edited_sim(name + ".lcmlog", edit)
            log = shoal_log.read_log(path)
            a = analyze(path)
            self.assertEqual((log.undecodable, a["log_undecodable"]), (1, 1), name)
            self.assertEqual(log.warnings, ["1 messages on Shoal channels did not decode (wrong "
                                            "size or fingerprint, a damaged string length) and "
                                            "were ignored"])
            if name == "reason_length_0":
                self.assertLess(len(log.decisions), len(clean.decisions))
            else:
                self.assertEqual(len(log.statuses), len(clean.statuses) - 1)
            self.check_against_analyze(log, a)

    def test_ids_beyond_the_followers_are_rejected(self):
        # run_data.cc's IdLimit: the scenario's 5 followers, whatever kinds are read.
        def edit(events):
            batches = [e[1] for e in events if e[0] == "SHOAL_CHANNEL" and batch_events(e[1])]
            i32(batches[100], batch_events(batches[100])[0] + 16, 50)  # a sender 50
            by = {}
            for k, e in enumerate(events):
                by.setdefault(e[0], []).append(k)
            h2, h3 = (events[by[c][3]][1] for c in ("SHOAL_HEALTH_2", "SHOAL_HEALTH_3"))
            h2[116:124] = struct.pack(">q", -1)  # window not reported: kept
            h3[124:132] = struct.pack(">d", math.inf)  # a non-finite window maximum
            health50 = bytearray(events[by["SHOAL_HEALTH_1"][3]][1])
            i32(health50, 16, 50)
            state9 = bytearray(events[by["SHOAL_STATE_1"][100]][1])
            i32(state9, 16, 9)
            at = len(events) // 2
            ts = events[at][2]
            events[at:at] = [["SHOAL_HEALTH_50", health50, ts], ["SHOAL_STATE_9", state9, ts],
                             ["SHOAL_RX_9", bytearray(events[by["SHOAL_RX_1"][0]][1]), ts]]

        path = self.edited_sim("ids.lcmlog", edit)
        log = shoal_log.read_log(path)
        a = analyze(path)
        self.assertEqual((log.rejected, a["log_rejected"]), (5, 5))
        self.assertEqual(sorted(log.states), [0, 1, 2, 3, 4, 5])
        self.assertNotIn(50, log.health)
        self.assertNotIn(9, log.rx)
        self.assertEqual(max(max(d.sender, d.receiver) for d in log.decisions), 5)
        self.assertEqual(sorted(h.lateness_window_count for h in log.health[2])[0], -1)
        self.check_against_analyze(log, a)
        only = shoal_log.read_log(path, channels=("STATE",))
        self.assertEqual((only.followers, only.states, only.rejected), (5, log.states, 1))
        self.assertNotIn(9, shoal_log.read_log(path, channels=("RX",)).rx)
        health = shoal_log.read_log(path, channels=("HEALTH",))
        self.assertEqual(health.health, log.health)

    def test_an_unknown_channel_status_is_dropped_invalid(self):
        # lcmtypes/README.md: a status above STATUS_DROPPED_DEAF (8) is a newer writer's kind
        # of drop, counted as dropped_invalid; a negative one is rejected.
        def edit(events):
            batches = [e[1] for e in events if e[0] == "SHOAL_CHANNEL" and batch_events(e[1])]
            batches[100][batch_events(batches[100])[0] + 52] = 9
            batches[101][batch_events(batches[101])[0] + 52] = 0xFF  # -1

        clean = shoal_log.read_log(self.sim_log)
        path = self.edited_sim("status9.lcmlog", edit)
        log = shoal_log.read_log(path)
        self.assertEqual(log.rejected, 1)
        self.assertEqual([d.status_name for d in log.decisions if d.status == 9],
                         ["dropped_invalid"])
        c, before = log.decision_counts(), clean.decision_counts()
        self.assertEqual(c["dropped_invalid"], before["dropped_invalid"] + 1)
        self.assertEqual(sum(c[k] for k in shoal_log.STATUS_NAMES.values()),
                         sum(before[k] for k in shoal_log.STATUS_NAMES.values()) - 1)
        a = analyze(path)
        if a["log_rejected"] == 2 and a["channel"]["dropped_invalid"] == before["dropped_invalid"]:
            self.skipTest("the shoal analyze in " + BUILD + " rejects an unknown status: built "
                          "before the rule that counts it as dropped_invalid")
        self.check_against_analyze(log, a)

    def test_a_log_recorded_twice_counts_each_message_once(self):
        path = os.path.join(TMP, "twice.lcmlog")
        with open(self.sim_log, "rb") as f:
            data = f.read()
        with open(path, "wb") as f:
            f.write(data + data)
        once, twice = shoal_log.read_log(self.sim_log), shoal_log.read_log(path)
        self.assertEqual(twice.decisions, once.decisions)
        self.assertEqual(twice.health, once.health)
        self.assertEqual(twice.repeated_decisions, len(once.decisions) + once.rejected)
        self.assertEqual(twice.repeated_health, sum(len(h) for h in once.health.values()))
        self.check_against_analyze(twice, analyze(path))

    def test_a_log_out_of_order_reads_as_shoal_analyze_reads_it(self):
        # Cut in two and joined the other way round: each process's health is its newest
        # report in mission time, as shoal analyze takes it, and the recording spans the
        # same time.
        events = read_events(self.run_log)
        half = len(events) // 2
        path = os.path.join(TMP, "swapped.lcmlog")
        write_events(path, events[half:] + events[:half])
        shutil.copy(self.run_log + ".key", path + ".key")
        log, a = shoal_log.read_log(path), analyze(path)
        self.check_against_analyze(log, a)
        health = shoal_log.summary(log)["health"]
        for p in a["loop"]["processes"]:
            self.assertEqual(health[str(p["id"])]["ticks"], p["ticks"], p["id"])
            self.assertEqual(health[str(p["id"])]["msgs_received"], p["msgs_received"], p["id"])
        self.assertEqual(a["wall_time_s"], analyze(self.run_log)["wall_time_s"])

    def test_the_first_event_is_looked_for_in_the_first_mebibyte_as_analyze_does(self):
        with open(self.sim_log, "rb") as f:
            data = f.read()
        for prefix, status in ((1048575, 0), (1048576, 2)):
            path = os.path.join(TMP, "prefix_%d.lcmlog" % prefix)
            with open(path, "wb") as f:
                f.write(bytes(prefix) + data)
            p = run([sys.executable, SCRIPT, path], ok=(status,))
            self.assertNotIn("Traceback", p.stderr)
            if status:
                self.assertIn("not an LCM log", p.stderr)
                self.assertIn("not an LCM log", analyze_refuses(path))
            else:
                self.check_against_analyze(shoal_log.read_log(path), analyze(path))

    def test_states_at_impossible_times_are_left_out(self):
        def edit(events):
            two = [e[1] for e in events if e[0] == "SHOAL_STATE_2"]
            three = [e[1] for e in events if e[0] == "SHOAL_STATE_3"]
            two[100][8:16] = struct.pack(">q", 10 ** 15)  # a state 31 years on
            three[50][8:16] = struct.pack(">q", -5 * 10 ** 6)  # and one 5 s before the start

        path = self.edited_sim("impossible_states.lcmlog", edit)
        log = shoal_log.read_log(path)
        a = analyze(path)
        self.assertEqual((len(log.damaged_states), log.states_negative_time,
                          log.states_after_end), (2, 1, 1))
        self.assertEqual((a["log_states_damaged"], a["log_states_negative_time"],
                          a["log_states_after_end"]), (2, 1, 1))
        self.assertEqual(sorted(s.vehicle_id for s in log.damaged_states), [2, 3])
        only = shoal_log.read_log(path, channels=("STATE",))
        self.assertEqual(only.states, log.states)
        self.assertEqual(len(only.damaged_states), 2)
        self.check_against_analyze(log, a)
        text = run([SHOAL, "analyze", path]).stdout
        damaged = [line.strip() for line in text.splitlines() if "vehicle states at" in line]
        self.assertEqual(damaged, [w for w in log.warnings if "vehicle states at" in w])
        summary = json.loads(run([sys.executable, SCRIPT, path, "--json"]).stdout)
        self.assertEqual(summary["states"], a["log_states"])
        self.assertEqual(summary["states_damaged"], 2)

    def test_decisions_at_impossible_times_are_left_out(self):
        def edit(events):
            batches = [e[1] for e in events if e[0] == "SHOAL_CHANNEL" and batch_events(e[1])]
            at = batch_events(batches[100])[0]
            batches[100][at + 28:at + 36] = struct.pack(">q", 10 ** 15)  # sent in 31 years
            for data in batches[len(batches) // 2:]:
                delivered = [k for k in batch_events(data) if data[k + 52] == 0]
                if delivered:
                    k = delivered[0]
                    send = struct.unpack_from(">q", data, k + 28)[0]
                    data[k + 44:k + 52] = struct.pack(">q", send - 1)  # delivered before sent
                    return
            self.fail("no delivered decision")

        path = self.edited_sim("impossible.lcmlog", edit)
        log = shoal_log.read_log(path)
        a = analyze(path)
        self.assertEqual((log.decisions_sent_impossible, log.decisions_delivered_impossible),
                         (1, 1))
        self.assertEqual(len(log.decisions) + 2,
                         len(shoal_log.read_log(self.sim_log).decisions))
        self.check_against_analyze(log, a)
        if tomllib is not None:  # the end from the logged scenario (Python 3.11+)
            self.assertEqual(log.end_utime, 40 * 10 ** 6)  # faults_short.toml: 40 s
            # its largest delay 0.3 s (a channel event's), rounded up, + 1 us, + 1 period
            self.assertEqual(log.last_delivery_utime, 40 * 10 ** 6 + 300001 + 20000)
            text = run([SHOAL, "analyze", path]).stdout
            damaged = [line.strip() for line in text.splitlines() if "channel events at" in line]
            self.assertEqual(damaged, [w for w in log.warnings if w.startswith("DAMAGED: ")])
        summary = json.loads(run([sys.executable, SCRIPT, path, "--json"]).stdout)
        self.assertEqual(summary["decisions"], log.decision_counts())
        self.assertEqual(summary["decisions_damaged"], 2)

    def test_an_unusable_types_directory_is_a_one_line_error(self):
        broken = os.path.join(TMP, "types_broken")
        stale = os.path.join(TMP, "types_stale")
        for d in (broken, stale):
            shutil.rmtree(d, ignore_errors=True)
        os.makedirs(os.path.join(broken, "shoal"))
        with open(os.path.join(broken, "shoal", "__init__.py"), "w") as f:
            f.write("this is not python(\n")
        shutil.copytree(os.path.join(PYDIR, "shoal"), os.path.join(stale, "shoal"),
                        ignore=shutil.ignore_patterns("__pycache__", "vehicle_state_t.py"))
        init = os.path.join(stale, "shoal", "__init__.py")
        with open(init) as f:
            lines = [x for x in f if "vehicle_state_t" not in x]
        with open(init, "w") as f:
            f.writelines(lines)
        for where, words in ((broken, "do not import (SyntaxError"),
                             (stale, "lack vehicle_state_t")):
            for extra, env in ((["--types", where], None), ([], {"SHOAL_PYTHON_TYPES": where})):
                p = run([sys.executable, SCRIPT, self.sim_log, *extra], ok=(2,), env=env)
                self.assertNotIn("Traceback", p.stderr)
                self.assertEqual(len(p.stderr.splitlines()), 1, p.stderr)
                self.assertIn(words, p.stderr)
            with self.assertRaises(shoal_log.ShoalLogError):
                shoal_log.read_log(self.sim_log, types_dir=where)
        self.assertGreater(shoal_log.read_log(self.sim_log).events, 0)  # types still usable

    def test_a_retimed_log_is_read_as_shoal_analyze_reads_it(self):
        retimed = os.path.join(TMP, "sim.mission.lcmlog")
        run([SHOAL, "retime", self.sim_log, "--out", retimed, "--force", "--quiet"])
        events = read_events(retimed)
        self.assertEqual(events[0][0], "SHOAL-RETIMED")
        log = shoal_log.read_log(retimed)
        a = analyze(retimed)
        self.assertEqual(log.events, shoal_log.read_log(self.sim_log).events)
        self.assertEqual(log.retimed_from["log"], os.path.basename(self.sim_log))
        self.check_against_analyze(log, a)
        summary = json.loads(run([sys.executable, SCRIPT, retimed, "--json"]).stdout)
        self.assertEqual(summary["retimed_from"], a["retimed_from"])
        self.assertEqual(summary["events"], a["log_events"])
        self.assertIn("RETIMED log (event times in mission time) of sim.lcmlog",
                      run([sys.executable, SCRIPT, retimed]).stdout)
        # Not the first event: a foreign event like any other, counted.
        moved = os.path.join(TMP, "marker_second.lcmlog")
        write_events(moved, [events[1], events[0]] + events[2:])
        log = shoal_log.read_log(moved)
        a = analyze(moved)
        self.assertIsNone(log.retimed_from)
        self.assertEqual(log.events, len(events))
        self.check_against_analyze(log, a)

    def test_a_retimed_copy_of_a_damaged_log_is_damaged(self):
        events = event_offsets(self.run_log)
        middle = events[len(events) // 2][0]

        def edit(b):
            b[middle] = 0  # a sync word

        path = self.damaged("damaged_for_retime.lcmlog", edit)
        retimed = os.path.join(TMP, "damaged.mission.lcmlog")
        run([SHOAL, "retime", path, "--out", retimed, "--force", "--quiet"])
        log = shoal_log.read_log(retimed)
        a = analyze(retimed)
        self.assertTrue(a["damaged"])
        self.assertTrue(log.damaged)
        self.assertTrue(log.warnings[0].startswith("the original log: "), log.warnings)
        self.assertEqual(log.warnings, a["warnings"])
        self.check_against_analyze(log, a)

    def test_more_damaged_places_than_are_listed(self):
        events = event_offsets(self.run_log)
        places = [events[k][0] for k in range(100, len(events) - 100, (len(events) - 200) // 25)]
        self.assertGreaterEqual(len(places), 25)

        def edit(b):
            for at in places[:25]:
                b[at] = 0  # its sync word

        path = self.damaged("damaged_25.lcmlog", edit)
        log = shoal_log.read_log(path)
        a = analyze(path)
        self.assertEqual(len(log.warnings), 21)
        self.assertEqual(log.warnings[-1], path + ": more damaged places follow (only the first "
                                                  "20 are listed)")
        self.assertEqual(log.warnings, a["warnings"])
        self.check_against_analyze(log, a)

    def test_what_is_no_log_is_a_clear_error(self):
        junk = os.path.join(TMP, "junk.lcmlog")
        with open(junk, "wb") as f:
            f.write(os.urandom(4096).replace(shoal_log.SYNC_BYTES, b"    "))
        empty = os.path.join(TMP, "empty.lcmlog")
        open(empty, "wb").close()
        for path, words in ((junk, "not an LCM log"), (empty, "empty file"),
                            (os.path.join(TMP, "missing.lcmlog"), "cannot read log")):
            p = run([sys.executable, SCRIPT, path], ok=(2,))
            self.assertIn(words, p.stderr)
            self.assertNotIn("Traceback", p.stderr)
            self.assertIn(words, analyze_refuses(path))

    def test_the_cli_finds_the_types_from_the_build_and_the_source_tree(self):
        # The build's copy finds the types beside it.
        summary = json.loads(run([sys.executable, os.path.join(PYDIR, "shoal_log.py"),
                                  self.run_log, "--json"],
                                 env={"SHOAL_PYTHON_TYPES": ""}).stdout)
        self.assertEqual([v["states"] for v in summary["vehicles"]], [501] * 6)
        self.assertEqual(summary["authentication"]["unauthenticated"], 0)
        # The source tree's script finds build/python from python/ (a build named build)
        # or takes --types; a copy anywhere else takes --types or SHOAL_PYTHON_TYPES.
        source_script = os.path.join(SOURCE, "python", "shoal_log.py")
        alone = os.path.join(TMP, "alone")
        os.makedirs(alone, exist_ok=True)
        shutil.copy(source_script, alone)
        alone_script = os.path.join(alone, "shoal_log.py")
        for script, extra, env in ((source_script, ["--types", PYDIR], None),
                                   (alone_script, ["--types", PYDIR], None),
                                   (alone_script, [], {"SHOAL_PYTHON_TYPES": PYDIR})):
            p = run([sys.executable, script, self.run_log, "--json", *extra], env=env)
            self.assertEqual(json.loads(p.stdout)["states"], summary["states"])
        for extra in ([], ["--types", TMP]):
            p = run([sys.executable, alone_script, self.run_log, *extra], ok=(2,),
                    env={"SHOAL_PYTHON_TYPES": ""})
            self.assertIn("the generated Python message types", p.stderr)
            self.assertIn("are not in " + (TMP if extra else alone), p.stderr)
            self.assertNotIn("Traceback", p.stderr)


class Trailers(unittest.TestCase):
    def test_python_siphash_equals_the_reference_and_libsodium(self):
        self.assertEqual(shoal_log.siphash128_python(bytes(range(16)), b"").hex(),
                         "a3817f04ba25a8e66df67214c7550293")
        if shoal_log.siphash128 is shoal_log.siphash128_python:
            self.skipTest("libsodium is not loadable here: nothing to compare with")
        rng = random.Random(5)
        for n in list(range(0, 80)) + [255, 256, 1000, 4093]:
            key = bytes(rng.randrange(256) for _ in range(16))
            data = bytes(rng.randrange(256) for _ in range(n))
            self.assertEqual(shoal_log.siphash128_python(key, data),
                             shoal_log.siphash128(key, data), n)

    def test_the_hmac_trailer_of_older_logs_still_verifies(self):
        import hashlib
        import hmac
        key = bytes(range(32))
        v = shoal_log.Verifier(key)
        payload = b"a state of an older log"
        tag = hmac.new(key, b"SHOAL_STATE_3\0" + payload, hashlib.sha512).digest()[:32]
        old = payload + b"SHOALMAC" + tag
        self.assertEqual(shoal_log.trailer_bytes(old), 40)
        self.assertEqual(v.verify("SHOAL_STATE_3", old), payload)
        self.assertIsNone(v.verify("SHOAL_STATE_4", old))
        self.assertIsNone(v.verify("SHOAL_STATE_3", old[:-1] + bytes([old[-1] ^ 1])))
        new = v.sign("SHOAL_STATE_3", payload)
        self.assertEqual(new[-24:-16], b"SHOALSIP")
        self.assertEqual(v.verify("SHOAL_STATE_3", new), payload)
        self.assertIsNone(shoal_log.Verifier(bytes(32)).verify("SHOAL_STATE_3", new))


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0], "-v"])
