// Authentication of a run's LCM messages. Anyone on the host can publish on a run's
// multicast group; a per-run secret key, drawn by shoal run and handed to its processes
// outside their command lines (SHOAL_BUS_KEY, docs/run.md), lets every receiver drop what
// was not sent by a process of the run.
//
// Wire format: the message's bytes, then a trailer: an 8-byte magic and a tag over the
// channel name, a NUL and the message's bytes, under the run's key. The channel is covered
// so that a message cannot be moved to another channel; the trailer is appended after the
// LCM encoding so that the LCM types stay as they are, and it is stripped before anything
// decodes. The magic lets a reader without the key tell an authenticated message from one
// written without a trailer (shoal sim, older logs): 8 bytes, so that a plain message's
// tail matches by chance with probability 2^-64. Two trailers:
//  - "SHOALSIP" and a 16-byte SipHash-2-4 tag (its 128-bit output, runtime/siphash.h),
//    keyed with 16 bytes derived from the run's key (libsodium's crypto_kdf_derive_from_key,
//    subkey 1, context "SHOALSIP"): what Sign writes, kTrailerBytes in all.
//  - "SHOALMAC" and HMAC-SHA-512/256 (libsodium's crypto_auth_hmacsha512256) under the
//    run's key: what Shoal wrote before; Verify still accepts it, so that the logs recorded
//    then verify with their keys.
// SipHash is a keyed pseudorandom function designed to authenticate short messages: without
// the key a forged message passes with probability 2^-128 per try, and every try is a
// datagram that receivers check as it comes. It costs an eighth of HMAC-SHA-512/256 for a
// state; in a 64-vehicle lockstep run HMAC was half of the channel emulator's CPU, which is
// every window's critical path (docs/benchmarks.md).
#pragma once

#include <sodium/crypto_auth_hmacsha512256.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace shoal::bus_auth {

constexpr int kKeyBytes = 32;
constexpr int kMagicBytes = 8;
constexpr int kMacBytes = 16;
/// What Sign writes: "SHOALSIP" and the SipHash tag.
constexpr int kTrailerBytes = kMagicBytes + kMacBytes;
/// The trailer of older logs: "SHOALMAC" and HMAC-SHA-512/256.
constexpr int kHmacMacBytes = 32;
constexpr int kHmacTrailerBytes = kMagicBytes + kHmacMacBytes;
/// The environment variable through which shoal run hands the key to its processes:
/// 64 hex digits. /proc/PID/environ is readable by the same user only; a command line
/// is readable by everyone.
constexpr const char* kKeyEnv = "SHOAL_BUS_KEY";

using Key = std::array<unsigned char, kKeyBytes>;

/// A fresh random key (libsodium's randombytes_buf).
Key NewKey();
/// 64 lower-case hex digits.
std::string ToHex(const Key& key);
/// Exactly 64 hex digits (surrounding white space allowed); false with *error otherwise.
bool ParseKey(std::string_view text, Key* key, std::string* error);
/// Reads a key file (64 hex digits); false with *error (naming the file) otherwise.
bool ReadKeyFile(const std::string& path, Key* key, std::string* error);
/// Writes `key` to a new file `path` with mode 0600 (an existing file is replaced by a
/// new one, never written through: a link planted there is not followed).
bool WriteKeyFile(const std::string& path, const Key& key, std::string* error);

/// Signs and verifies under one key. Holds the SipHash key derived from it, and HMAC's
/// state after the key's inner and outer pads for the trailers of older logs.
class Authenticator {
 public:
  explicit Authenticator(const Key& key);
  /// Writes the trailer for `data` sent on `channel` to out[0, kTrailerBytes).
  void Sign(std::string_view channel, const void* data, int size, unsigned char* out) const;
  /// The size of the message without its trailer if `data` ends with a trailer (either
  /// kind) that verifies for `channel`; -1 otherwise (no trailer, another key, another
  /// channel, any changed bit).
  int Verify(std::string_view channel, const void* data, int size) const;

 private:
  void Mac(std::string_view channel, const void* data, int size, unsigned char* out) const;
  void HmacMac(std::string_view channel, const void* data, int size, unsigned char* out) const;
  unsigned char sip_key_[16];
  crypto_auth_hmacsha512256_state keyed_;  // after the key's pads
};

/// Authenticator(key).Sign / .Verify, for a single message.
void Sign(const Key& key, std::string_view channel, const void* data, int size,
          unsigned char* out);
int Verify(const Key& key, std::string_view channel, const void* data, int size);
/// The size of the trailer `data` ends with, by its magic (unverified: for readers without
/// the key): kTrailerBytes, kHmacTrailerBytes, or 0 for none.
int TrailerBytes(const void* data, int size);
/// Whether `data` ends with a trailer's magic.
inline bool HasTrailer(const void* data, int size) { return TrailerBytes(data, size) > 0; }

/// What an unauthenticated run's status messages say (the analysis of a log looks for it).
constexpr const char* kInsecureNote = "bus not authenticated (--insecure)";

/// What a process was told about authentication: its key, or --insecure.
struct Setting {
  bool insecure = false;
  std::optional<Key> key;  // set unless insecure
};
/// The key of a process from SHOAL_BUS_KEY unless `insecure`. False (with a message for
/// the user in *error that says how to give a key) if neither is there or the key is
/// malformed.
bool SettingFromEnvironment(bool insecure, Setting* setting, std::string* error);
/// SettingFromEnvironment for a process's main(): says why on stderr ("<name>: ...").
bool SettingOrReport(bool insecure, const std::string& name, Setting* setting);
/// What a process writes to its log on exit: how many messages failed authentication.
std::string ExitNote(const Setting& setting, std::int64_t rejected);
/// The count of the last ExitNote line in a process's output (shoal run reads it back from
/// each process's output file: forgeries sent to a vehicle's own port reach no one else).
/// False if `output` holds none (the process was killed, or ran with --insecure).
bool ParseExitNote(const std::string& output, std::int64_t* rejected);

}  // namespace shoal::bus_auth
