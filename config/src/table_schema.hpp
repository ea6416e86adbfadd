#pragma once

// The fields of one TOML table and the struct they fill. Each field is declared once (key, struct
// member, codec with its range, one-line doc, required or not) and that single declaration drives
// loading, error messages and the commented TOML that format_*_toml() print. Defaults are never
// restated here: a missing optional key leaves the struct member's initialiser in place, and the
// printed default file is the default-constructed struct written out.

#include <algorithm>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "closest_key.hpp"
#include "read_context.hpp"
#include "source_error.hpp"

namespace ultrasim::config {

enum class Presence { kOptional, kRequired };

template <typename T>
struct IsOptional : std::false_type {};
template <typename T>
struct IsOptional<std::optional<T>> : std::true_type {};

// One key of a table, type-erased over its codec.
template <typename S>
struct Field {
  std::string key;
  std::string doc;
  std::string allowed;
  Presence presence = Presence::kOptional;
  // Reads node into the member of out; throws ConfigError naming dotted_key.
  std::function<void(const toml::node& node, const ReadContext& ctx, const std::string& dotted_key,
                     S& out)>
      read;
  // The member as TOML value text, or nothing for an unset std::optional member.
  std::function<std::optional<std::string>(const S& in, const WriteContext& ctx)> write;
};

// Declares a field. The member may be codec's value_type, or std::optional of it: then a missing
// key leaves it unset and an unset member is written as a comment.
template <typename S, typename Member, typename Codec>
Field<S> field(std::string key, Member S::*member, Codec codec, std::string doc,
               Presence presence = Presence::kOptional) {
  using Value = typename Codec::value_type;
  static_assert(std::is_same_v<Member, Value> || std::is_same_v<Member, std::optional<Value>>,
                "the codec's value_type must match the struct member");
  Field<S> f;
  f.key = std::move(key);
  f.doc = std::move(doc);
  f.allowed = codec.allowed();
  f.presence = presence;
  f.read = [member, codec](const toml::node& node, const ReadContext& ctx,
                           const std::string& dotted_key,
                           S& out) { out.*member = codec.read(node, ctx, dotted_key); };
  f.write = [member, codec](const S& in, const WriteContext& ctx) -> std::optional<std::string> {
    if constexpr (IsOptional<Member>::value) {
      if (!(in.*member).has_value()) return std::nullopt;
      return codec.write(*(in.*member), ctx);
    } else {
      return codec.write(in.*member, ctx);
    }
  };
  return f;
}

// Declares a field of a struct the table's struct holds (FemSettings::contact.model as the key
// "contact" of [fem]): the same as field() on the inner struct.
template <typename S, typename Inner, typename Member, typename Codec>
Field<S> field(std::string key, Inner S::*outer, Member Inner::*member, Codec codec,
               std::string doc, Presence presence = Presence::kOptional) {
  Field<Inner> inner = field(std::move(key), member, std::move(codec), std::move(doc), presence);
  Field<S> f;
  f.key = std::move(inner.key);
  f.doc = std::move(inner.doc);
  f.allowed = std::move(inner.allowed);
  f.presence = presence;
  f.read = [outer, read = std::move(inner.read)](const toml::node& node, const ReadContext& ctx,
                                                 const std::string& dotted_key, S& out) {
    read(node, ctx, dotted_key, out.*outer);
  };
  f.write = [outer, write = std::move(inner.write)](const S& in, const WriteContext& ctx) {
    return write(in.*outer, ctx);
  };
  return f;
}

// "prefix.key", or "key" at the top level.
inline std::string dotted(std::string_view prefix, std::string_view key) {
  return prefix.empty() ? std::string(key) : std::string(prefix) + "." + std::string(key);
}

// Comment lines for a field: its one-line doc, then what it accepts.
inline void write_comment(std::string& out, std::string_view doc, std::string_view allowed,
                          Presence presence) {
  out += "# ";
  out += doc;
  out += "\n# ";
  if (presence == Presence::kRequired) out += "required; ";
  out += "allowed: ";
  out += allowed;
  out += '\n';
}

// Whether a starts before b in the source.
inline bool precedes(const toml::source_region& a, const toml::source_region& b) {
  return a.begin.line != b.begin.line ? a.begin.line < b.begin.line
                                      : a.begin.column < b.begin.column;
}

// Throws "unknown key" for key, suggesting the closest of known when one is close.
[[noreturn]] inline void fail_unknown_key(const ReadContext& ctx, const toml::key& key,
                                          const std::string& table_key,
                                          const std::vector<std::string>& known,
                                          std::string known_list) {
  std::string problem = "unknown key";
  if (const auto suggestion = closest_key(key.str(), known)) {
    problem += " (did you mean \"" + *suggestion + "\"?)";
  }
  fail_at(ctx, key.source(), dotted(table_key, key.str()), std::move(problem),
          std::move(known_list));
}

template <typename S>
class TableSchema {
 public:
  using Check = std::function<void(const S& value, const toml::table& table, const ReadContext& ctx,
                                   const std::string& table_key)>;

  TableSchema& add(Field<S> f) {
    fields_.push_back(std::move(f));
    return *this;
  }

  // A rule across fields (e.g. min < max), run after every field was read; throws ConfigError.
  TableSchema& check(Check rule) {
    checks_.push_back(std::move(rule));
    return *this;
  }

  std::vector<std::string> keys() const {
    std::vector<std::string> names;
    for (const Field<S>& f : fields_) names.push_back(f.key);
    return names;
  }

  // The known keys, for "allowed:" of an unknown key.
  std::string key_list() const {
    std::string text;
    for (const Field<S>& f : fields_) text += (text.empty() ? "" : ", ") + f.key;
    return text;
  }

  // Reads table into out (which starts with the defaults). table_key is the table's dotted name for
  // messages; anchor is where "missing required key" points (the table's header, or the start of
  // the file when the whole table is missing). Throws ConfigError on the first problem, in the
  // order unknown keys (first in the file), then fields in declaration order, then checks.
  void read(const toml::table& table, const toml::source_region& anchor, const ReadContext& ctx,
            const std::string& table_key, S& out) const {
    reject_unknown_keys(table, ctx, table_key);
    for (const Field<S>& f : fields_) {
      const std::string key = dotted(table_key, f.key);
      if (const toml::node* node = table.get(f.key)) {
        f.read(*node, ctx, key, out);
      } else if (f.presence == Presence::kRequired) {
        fail_at(ctx, anchor, key, "missing required key", f.allowed);
      }
    }
    for (const Check& rule : checks_) rule(out, table, ctx, table_key);
  }

  // "key = value" lines, each after its comment.
  void write(const S& value, const WriteContext& ctx, std::string& out) const {
    for (const Field<S>& f : fields_) {
      write_comment(out, f.doc, f.allowed, f.presence);
      if (const std::optional<std::string> text = f.write(value, ctx)) {
        out += f.key + " = " + *text + "\n";
      } else {
        out += "# " + f.key + " is unset\n";
      }
    }
  }

 private:
  void reject_unknown_keys(const toml::table& table, const ReadContext& ctx,
                           const std::string& table_key) const {
    // toml::table iterates in key order; report the unknown key that comes first in the file.
    const toml::key* first = nullptr;
    for (auto&& [key, node] : table) {
      const bool known = std::any_of(fields_.begin(), fields_.end(),
                                     [&](const Field<S>& f) { return f.key == key.str(); });
      if (!known && (first == nullptr || precedes(key.source(), first->source()))) first = &key;
    }
    if (first == nullptr) return;
    fail_unknown_key(ctx, *first, table_key, keys(), key_list());
  }

  std::vector<Field<S>> fields_;
  std::vector<Check> checks_;
};

}  // namespace ultrasim::config
