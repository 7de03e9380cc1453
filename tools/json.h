// A minimal JSON object writer for --json outputs (flat and nested objects, numbers,
// strings, booleans, null for non-finite numbers).
#pragma once

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace shoal {

class JsonWriter {
 public:
  JsonWriter() { out_ << "{"; }

  JsonWriter& Num(const std::string& key, double v) {
    Key(key);
    if (std::isfinite(v)) {
      char buf[40];
      std::snprintf(buf, sizeof(buf), "%.10g", v);
      out_ << buf;
    } else {
      out_ << "null";
    }
    return *this;
  }
  JsonWriter& Int(const std::string& key, long long v) {
    Key(key);
    out_ << v;
    return *this;
  }
  JsonWriter& Bool(const std::string& key, bool v) {
    Key(key);
    out_ << (v ? "true" : "false");
    return *this;
  }
  JsonWriter& Str(const std::string& key, const std::string& v) {
    Key(key);
    out_ << Quote(v);
    return *this;
  }
  /// Inserts an already serialised JSON value (object or array).
  JsonWriter& Raw(const std::string& key, const std::string& json) {
    Key(key);
    out_ << json;
    return *this;
  }
  /// An array of numbers (null for non-finite entries).
  JsonWriter& NumArray(const std::string& key, const std::vector<double>& v) {
    return Raw(key, Array(v));
  }
  std::string Done() { return out_.str() + "}"; }

  /// A number as JSON text: "null" if not finite.
  static std::string Number(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[40];
    std::snprintf(buf, sizeof(buf), "%.10g", v);
    return buf;
  }
  /// An array of numbers.
  static std::string Array(const std::vector<double>& v) {
    std::string o = "[";
    for (std::size_t i = 0; i < v.size(); ++i) o += (i ? "," : "") + Number(v[i]);
    return o + "]";
  }
  /// An array of already serialised JSON values.
  static std::string List(const std::vector<std::string>& items) {
    std::string o = "[";
    for (std::size_t i = 0; i < items.size(); ++i) o += (i ? "," : "") + items[i];
    return o + "]";
  }

  static std::string Quote(const std::string& s) {
    std::string o = "\"";
    for (char c : s) {
      switch (c) {
        case '"': o += "\\\""; break;
        case '\\': o += "\\\\"; break;
        case '\n': o += "\\n"; break;
        case '\t': o += "\\t"; break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", c);
            o += buf;
          } else {
            o += c;
          }
      }
    }
    return o + "\"";
  }

 private:
  void Key(const std::string& k) {
    if (!first_) out_ << ",";
    first_ = false;
    out_ << Quote(k) << ":";
  }
  std::ostringstream out_;
  bool first_ = true;
};

}  // namespace shoal
