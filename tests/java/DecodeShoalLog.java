import java.io.DataInput;
import java.io.IOException;
import java.nio.charset.StandardCharsets;
import java.util.Arrays;
import java.util.Map;
import java.util.TreeMap;

import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMDataOutputStream;
import lcm.lcm.LCMEncodable;
import lcm.logging.Log;
import lcm.spy.LCMTypeDatabase;

/**
 * Decodes a Shoal LCM log through the Java classes of shoal_lcmtypes.jar, finding each
 * message's class the way lcm-spy does: lcm.spy.LCMTypeDatabase (lcm-spy's own lookup,
 * over the classes on the class path and in $CLASSPATH) by the 8-byte fingerprint the
 * message starts with, then the class's DataInput constructor.
 *
 * <pre>
 * java -cp lcm.jar:shoal_lcmtypes.jar:decode_shoal_log.jar DecodeShoalLog LOG
 * java -cp ... DecodeShoalLog --types shoal.vehicle_state_t,shoal.channel_event_t
 * </pre>
 *
 * Prints one line per fact, its keyword first (tests/java/java_decode_test.cc reads them):
 * <pre>
 * log PATH events N undecoded N
 * channel NAME type CLASS events N reencoded_equal N trailer_auth N trailer_none N trailer_other N
 * vehicle ID states N
 * state ID first|last utime U seq S x X y Y z Z bits XBITS YBITS ZBITS
 * decisions batches N events N status0 N ... status8 N status_other N
 * health ID reports N
 * status reports N first STATE scenario NAME followers N
 * type CLASS fingerprint HEX found CLASS|none
 * </pre>
 * A message of a secured run carries a trailer after its LCM encoding (docs/run.md
 * "Authentication"): 24 bytes, the magic SHOALSIP and a SipHash tag; 40 bytes in logs written
 * before, SHOALMAC and an HMAC. The generated decoders read their fields from the stream and
 * leave the trailer unread. reencoded_equal counts the messages
 * whose decoded object encodes again to exactly the bytes before the trailer.
 */
public final class DecodeShoalLog {
  private static final byte[] TRAILER_MAGIC = "SHOALSIP".getBytes(StandardCharsets.US_ASCII);
  private static final int TRAILER_BYTES = 24;
  private static final byte[] HMAC_TRAILER_MAGIC = "SHOALMAC".getBytes(StandardCharsets.US_ASCII);
  private static final int HMAC_TRAILER_BYTES = 40;
  private static final int STATUS_VALUES = 9;

  private static final class ChannelCounts {
    String type = "none";
    long events, reencodedEqual, trailerAuth, trailerNone, trailerOther;
  }

  private static final class VehicleStates {
    long count;
    shoal.vehicle_state_t first, last;
  }

  private final LCMTypeDatabase types = new LCMTypeDatabase();
  private final Map<String, ChannelCounts> channels = new TreeMap<>();
  private final Map<Integer, VehicleStates> vehicles = new TreeMap<>();
  private final Map<Integer, Long> healthReports = new TreeMap<>();
  private final long[] statusCounts = new long[STATUS_VALUES + 1];
  private long events, undecoded, batches, decisions, statusReports;
  private shoal.run_status_t firstStatus;

  public static void main(String[] args) throws Exception {
    if (args.length == 2 && args[0].equals("--types")) {
      new DecodeShoalLog().printTypes(args[1].split(","));
      return;
    }
    if (args.length != 1) {
      System.err.println("usage: DecodeShoalLog LOG | DecodeShoalLog --types CLASS,CLASS,...");
      System.exit(2);
    }
    DecodeShoalLog d = new DecodeShoalLog();
    d.readLog(args[0]);
    d.print(args[0]);
  }

  /** lcm-spy's lookup for each named class: its LCM_FINGERPRINT, and what that finds. */
  private void printTypes(String[] names) throws Exception {
    for (String name : names) {
      long fingerprint = Class.forName(name).getField("LCM_FINGERPRINT").getLong(null);
      Class<?> found = types.getClassByFingerprint(fingerprint);
      System.out.printf("type %s fingerprint %016x found %s%n", name, fingerprint,
                        found == null ? "none" : found.getName());
    }
  }

  private void readLog(String path) throws IOException {
    Log log = new Log(path, "r");
    try {
      for (;;) {
        Log.Event e;
        try {
          e = log.readNext();
        } catch (java.io.EOFException end) {
          break;
        }
        ++events;
        handle(e.channel, e.data);
      }
    } finally {
      log.close();
    }
  }

  /** What lcm-spy does with a message (lcm.spy.Spy's subscriber), then the counts. */
  private void handle(String channel, byte[] data) throws IOException {
    ChannelCounts c = channels.computeIfAbsent(channel, k -> new ChannelCounts());
    ++c.events;
    LCMDataInputStream ins = new LCMDataInputStream(data);
    long fingerprint = ins.available() >= 8 ? ins.readLong() : -1;
    ins.reset();
    Class<?> cls = types.getClassByFingerprint(fingerprint);
    Object o;
    try {
      o = cls.getConstructor(DataInput.class).newInstance(ins);
    } catch (Exception | LinkageError ex) {  // unknown fingerprint (cls null) included
      ++undecoded;
      return;
    }
    c.type = cls.getName();
    LCMDataOutputStream out = new LCMDataOutputStream();
    ((LCMEncodable) o).encode(out);
    countTrailer(c, data, out.toByteArray());
    record(channel, o);
  }

  private static void countTrailer(ChannelCounts c, byte[] data, byte[] encoded) {
    int n = encoded.length;
    if (data.length >= n && Arrays.equals(Arrays.copyOf(data, n), encoded)) ++c.reencodedEqual;
    int rest = data.length - n;
    if (rest == 0) {
      ++c.trailerNone;
    } else if ((rest == TRAILER_BYTES
                && Arrays.equals(Arrays.copyOfRange(data, n, n + TRAILER_MAGIC.length), TRAILER_MAGIC))
               || (rest == HMAC_TRAILER_BYTES
                   && Arrays.equals(Arrays.copyOfRange(data, n, n + HMAC_TRAILER_MAGIC.length),
                                    HMAC_TRAILER_MAGIC))) {
      ++c.trailerAuth;
    } else {
      ++c.trailerOther;
    }
  }

  private void record(String channel, Object o) {
    if (o instanceof shoal.vehicle_state_t && channel.startsWith("SHOAL_STATE_")) {
      shoal.vehicle_state_t s = (shoal.vehicle_state_t) o;
      VehicleStates v = vehicles.computeIfAbsent(s.vehicle_id, k -> new VehicleStates());
      ++v.count;
      if (v.first == null || s.utime < v.first.utime) v.first = s;
      if (v.last == null || s.utime > v.last.utime) v.last = s;
    } else if (o instanceof shoal.channel_events_t) {
      shoal.channel_events_t b = (shoal.channel_events_t) o;
      ++batches;
      for (shoal.channel_event_t e : b.events) {
        ++decisions;
        ++statusCounts[e.status >= 0 && e.status < STATUS_VALUES ? e.status : STATUS_VALUES];
      }
    } else if (o instanceof shoal.health2_t) {
      healthReports.merge(((shoal.health2_t) o).vehicle_id, 1L, Long::sum);
    } else if (o instanceof shoal.run_status_t) {
      if (statusReports++ == 0) firstStatus = (shoal.run_status_t) o;
    }
  }

  private static void printState(int id, String which, shoal.vehicle_state_t s) {
    System.out.printf("state %d %s utime %d seq %d x %s y %s z %s bits %016x %016x %016x%n", id,
                      which, s.utime, s.seq, s.eta[0], s.eta[1], s.eta[2],
                      Double.doubleToRawLongBits(s.eta[0]), Double.doubleToRawLongBits(s.eta[1]),
                      Double.doubleToRawLongBits(s.eta[2]));
  }

  private void print(String path) {
    System.out.printf("log %s events %d undecoded %d%n", path, events, undecoded);
    for (Map.Entry<String, ChannelCounts> e : channels.entrySet()) {
      ChannelCounts c = e.getValue();
      System.out.printf("channel %s type %s events %d reencoded_equal %d trailer_auth %d"
                        + " trailer_none %d trailer_other %d%n", e.getKey(), c.type, c.events,
                        c.reencodedEqual, c.trailerAuth, c.trailerNone, c.trailerOther);
    }
    for (Map.Entry<Integer, VehicleStates> e : vehicles.entrySet()) {
      System.out.printf("vehicle %d states %d%n", e.getKey(), e.getValue().count);
      printState(e.getKey(), "first", e.getValue().first);
      printState(e.getKey(), "last", e.getValue().last);
    }
    StringBuilder status = new StringBuilder();
    for (int i = 0; i < STATUS_VALUES; ++i) status.append(" status").append(i).append(' ').append(statusCounts[i]);
    System.out.printf("decisions batches %d events %d%s status_other %d%n", batches, decisions, status,
                      statusCounts[STATUS_VALUES]);
    for (Map.Entry<Integer, Long> e : healthReports.entrySet()) {
      System.out.printf("health %d reports %d%n", e.getKey(), e.getValue());
    }
    System.out.printf("status reports %d first %s scenario %s followers %d%n", statusReports,
                      firstStatus == null ? "none" : firstStatus.state,
                      firstStatus == null ? "none" : firstStatus.scenario_name,
                      firstStatus == null ? 0 : firstStatus.followers);
  }
}
