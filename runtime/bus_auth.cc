#include "runtime/bus_auth.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "runtime/siphash.h"

namespace shoal::bus_auth {
namespace {

constexpr unsigned char kMagic[kMagicBytes] = {'S', 'H', 'O', 'A', 'L', 'S', 'I', 'P'};
constexpr unsigned char kHmacMagic[kMagicBytes] = {'S', 'H', 'O', 'A', 'L', 'M', 'A', 'C'};
constexpr char kSipContext[crypto_kdf_CONTEXTBYTES] = {'S', 'H', 'O', 'A', 'L', 'S', 'I', 'P'};
constexpr std::uint64_t kSipSubkey = 1;

bool EndsWith(const void* data, int size, int trailer, const unsigned char* magic) {
  return data != nullptr && size >= trailer &&
         std::memcmp(static_cast<const unsigned char*>(data) + size - trailer, magic,
                     kMagicBytes) == 0;
}

/// The channel, a NUL and the message, as every tag covers them.
template <typename Update>
void Covered(std::string_view channel, const void* data, int size, Update update) {
  update(reinterpret_cast<const unsigned char*>(channel.data()), channel.size());
  const unsigned char separator = 0;  // channel names hold no NUL: no two inputs collide
  update(&separator, 1);
  update(static_cast<const unsigned char*>(data), static_cast<std::size_t>(size > 0 ? size : 0));
}

void EnsureSodium() {
  static const int ok = sodium_init();  // thread-safe, idempotent; < 0 only if unusable
  if (ok < 0) throw std::runtime_error("libsodium cannot be initialised");
}

using State = crypto_auth_hmacsha512256_state;

}  // namespace

Authenticator::Authenticator(const Key& key) {
  EnsureSodium();
  crypto_kdf_derive_from_key(sip_key_, sizeof(sip_key_), kSipSubkey, kSipContext, key.data());
  crypto_auth_hmacsha512256_init(&keyed_, key.data(), key.size());
}

void Authenticator::Mac(std::string_view channel, const void* data, int size,
                        unsigned char* out) const {
  SipHash128 h(sip_key_);
  Covered(channel, data, size, [&](const unsigned char* p, std::size_t n) { h.Update(p, n); });
  h.Final(out);
}

void Authenticator::HmacMac(std::string_view channel, const void* data, int size,
                            unsigned char* out) const {
  State st = keyed_;
  Covered(channel, data, size, [&](const unsigned char* p, std::size_t n) {
    crypto_auth_hmacsha512256_update(&st, p, n);
  });
  crypto_auth_hmacsha512256_final(&st, out);
}

void Authenticator::Sign(std::string_view channel, const void* data, int size,
                         unsigned char* out) const {
  std::memcpy(out, kMagic, kMagicBytes);
  Mac(channel, data, size, out + kMagicBytes);
}

int Authenticator::Verify(std::string_view channel, const void* data, int size) const {
  const int trailer = TrailerBytes(data, size);
  if (trailer == 0) return -1;
  const int payload = size - trailer;
  unsigned char mac[kHmacMacBytes];
  if (trailer == kTrailerBytes) {
    Mac(channel, data, payload, mac);
  } else {
    HmacMac(channel, data, payload, mac);
  }
  const auto* got = static_cast<const unsigned char*>(data) + payload + kMagicBytes;
  return sodium_memcmp(mac, got, static_cast<std::size_t>(trailer - kMagicBytes)) == 0 ? payload
                                                                                      : -1;
}

Key NewKey() {
  EnsureSodium();
  Key k;
  randombytes_buf(k.data(), k.size());
  return k;
}

std::string ToHex(const Key& key) {
  char hex[2 * kKeyBytes + 1];
  sodium_bin2hex(hex, sizeof(hex), key.data(), key.size());
  return hex;
}

bool ParseKey(std::string_view text, Key* key, std::string* error) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) {
    *error = "the key is empty (64 hex digits expected)";
    return false;
  }
  text = text.substr(first, text.find_last_not_of(" \t\r\n") - first + 1);
  size_t got = 0;
  const char* end = nullptr;
  Key k;
  if (text.size() != 2 * kKeyBytes ||
      sodium_hex2bin(k.data(), k.size(), text.data(), text.size(), nullptr, &got, &end) != 0 ||
      got != k.size() || end != text.data() + text.size()) {
    *error = "the key is not 64 hex digits (got " + std::to_string(text.size()) + " characters)";
    return false;
  }
  *key = k;
  return true;
}

bool ReadKeyFile(const std::string& path, Key* key, std::string* error) {
  // Non-blocking and regular files only: a FIFO or a device named as a key (or lying
  // next to a log as <log>.key) must be refused, never waited on or read without end.
  const int fd = open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    *error = path + ": cannot read the key file (" + std::strerror(errno) + ")";
    return false;
  }
  struct stat st {};
  std::string text(4097, '\0');
  ssize_t n = -1;
  if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) n = read(fd, text.data(), text.size());
  const int read_errno = errno;
  close(fd);
  if (!S_ISREG(st.st_mode)) {
    *error = path + ": not a key file (not a regular file)";
    return false;
  }
  if (n < 0) {
    *error = path + ": cannot read the key file (" + std::strerror(read_errno) + ")";
    return false;
  }
  if (n > 4096) {
    *error = path + ": not a key file (64 hex digits expected)";
    return false;
  }
  text.resize(static_cast<std::size_t>(n));
  if (!ParseKey(text, key, error)) {
    *error = path + ": " + *error;
    return false;
  }
  return true;
}

bool WriteKeyFile(const std::string& path, const Key& key, std::string* error) {
  if (unlink(path.c_str()) != 0 && errno != ENOENT) {
    *error = path + ": cannot replace the key file (" + std::strerror(errno) + ")";
    return false;
  }
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    *error = path + ": cannot create the key file (" + std::strerror(errno) + ")";
    return false;
  }
  const std::string text = ToHex(key) + "\n";
  const bool ok = write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  if (close(fd) != 0 || !ok) {
    *error = path + ": cannot write the key file";
    unlink(path.c_str());
    return false;
  }
  return true;
}

void Sign(const Key& key, std::string_view channel, const void* data, int size,
          unsigned char* out) {
  Authenticator(key).Sign(channel, data, size, out);
}

int Verify(const Key& key, std::string_view channel, const void* data, int size) {
  return Authenticator(key).Verify(channel, data, size);
}

int TrailerBytes(const void* data, int size) {
  if (EndsWith(data, size, kTrailerBytes, kMagic)) return kTrailerBytes;
  if (EndsWith(data, size, kHmacTrailerBytes, kHmacMagic)) return kHmacTrailerBytes;
  return 0;
}

bool SettingFromEnvironment(bool insecure, Setting* setting, std::string* error) {
  *setting = Setting();
  if (insecure) {
    setting->insecure = true;
    return true;
  }
  const char* env = std::getenv(kKeyEnv);
  if (env == nullptr) {
    *error = std::string("no bus key: shoal run hands its processes the run's key in the "
                         "environment; a process started by hand needs the same, e.g. ") +
             kKeyEnv + "=$(cat RUN.lcmlog.key), or --insecure to run without "
             "authentication (docs/run.md)";
    return false;
  }
  Key k;
  if (!ParseKey(env, &k, error)) {
    *error = std::string(kKeyEnv) + ": " + *error;
    return false;
  }
  setting->key = k;
  return true;
}

bool SettingOrReport(bool insecure, const std::string& name, Setting* setting) {
  std::string error;
  if (SettingFromEnvironment(insecure, setting, &error)) return true;
  std::fprintf(stderr, "%s: %s\n", name.c_str(), error.c_str());
  return false;
}

namespace {
constexpr const char* kExitNoteTail = " message(s) failed authentication (dropped)";
}  // namespace

std::string ExitNote(const Setting& setting, std::int64_t rejected) {
  if (setting.insecure) return kInsecureNote;
  return std::to_string(rejected) + kExitNoteTail;
}

bool ParseExitNote(const std::string& output, std::int64_t* rejected) {
  const std::size_t tail = output.rfind(kExitNoteTail);
  if (tail == std::string::npos) return false;
  // The digits just before the tail, after ": " (the process's name).
  std::size_t begin = tail;
  while (begin > 0 && output[begin - 1] >= '0' && output[begin - 1] <= '9') --begin;
  if (begin == tail || tail - begin > 18 || begin < 2 || output.compare(begin - 2, 2, ": ") != 0) {
    return false;
  }
  *rejected = std::stoll(output.substr(begin, tail - begin));
  return true;
}

}  // namespace shoal::bus_auth
