#pragma once

// A whole TOML file: its tables (each a TableSchema filling one member of Root), arrays of tables,
// and rules across tables. Like TableSchema, one declaration drives reading and writing.

#include <cstddef>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "array_codecs.hpp"
#include "table_schema.hpp"

namespace ultrasim::config {

template <typename Root>
class DocumentSchema {
 public:
  using Check =
      std::function<void(const Root& value, const toml::table& root, const ReadContext& ctx)>;

  // title: comment lines printed at the top of written files (without "# ").
  explicit DocumentSchema(std::vector<std::string> title) : title_(std::move(title)) {}

  // [key], filling root.*member.
  template <typename S>
  DocumentSchema& table(std::string key, S Root::*member, TableSchema<S> schema, std::string doc) {
    return table_with(
        std::move(key), std::move(schema), std::move(doc),
        [member](Root& root) -> S& { return root.*member; },
        [member](const Root& root) -> const S& { return root.*member; });
  }

  // [key], whose fields are members of Root itself.
  DocumentSchema& table(std::string key, TableSchema<Root> schema, std::string doc) {
    return table_with(
        std::move(key), std::move(schema), std::move(doc), [](Root& root) -> Root& { return root; },
        [](const Root& root) -> const Root& { return root; });
  }

  // [[key]] repeated, one element of root.*member per table; at least min_count of them.
  template <typename S>
  DocumentSchema& table_array(std::string key, std::vector<S> Root::*member, TableSchema<S> schema,
                              std::size_t min_count, std::string doc) {
    Section section;
    section.key = key;
    section.doc = std::move(doc);
    section.allowed = "at least " + std::to_string(min_count) + " [[" + key + "]] table" +
                      (min_count == 1 ? "" : "s") + " of: " + schema.key_list();
    section.read = [key, member, schema, min_count, allowed = section.allowed](
                       const toml::node* node, const toml::table& root, const ReadContext& ctx,
                       Root& out) {
      if (node == nullptr) {
        if (min_count > 0) fail_at(ctx, root.source(), key, "missing required table", allowed);
        return;
      }
      const toml::array* array = node->as_array();
      if (array == nullptr || !array->is_array_of_tables()) {
        fail_wrong_type(ctx, *node, key, "array of tables", allowed);
      }
      if (array->size() < min_count) {
        fail_at(ctx, node->source(), key, "too few tables: " + std::to_string(array->size()),
                allowed);
      }
      std::vector<S> items;
      items.reserve(array->size());
      for (std::size_t i = 0; i < array->size(); ++i) {
        const toml::table& item_table = *array->get(i)->as_table();
        S item{};
        schema.read(item_table, item_table.source(), ctx, element_key(key, i), item);
        items.push_back(std::move(item));
      }
      out.*member = std::move(items);
    };
    section.write = [key, member, schema, doc = section.doc](
                        const Root& in, const WriteContext& ctx, std::string& text) {
      if ((in.*member).empty()) {
        text += "\n# " + doc + "\n# (no [[" + key + "]] tables)\n";
      }
      for (const S& item : in.*member) {
        text += "\n# " + doc + "\n[[" + key + "]]\n";
        schema.write(item, ctx, text);
      }
    };
    sections_.push_back(std::move(section));
    return *this;
  }

  // A rule across tables, run after every table was read; throws ConfigError.
  DocumentSchema& check(Check rule) {
    checks_.push_back(std::move(rule));
    return *this;
  }

  // The whole document into a Root that starts from its defaults. Throws ConfigError on the first
  // problem: unknown top-level keys first, then tables in declaration order, then checks.
  Root read(const toml::table& root, const ReadContext& ctx) const {
    reject_unknown_tables(root, ctx);
    Root out{};
    for (const Section& section : sections_) {
      section.read(root.get(section.key), root, ctx, out);
    }
    for (const Check& rule : checks_) rule(out, root, ctx);
    return out;
  }

  std::string write(const Root& value, const WriteContext& ctx) const {
    std::string text;
    for (const std::string& line : title_) text += "# " + line + "\n";
    for (const Section& section : sections_) section.write(value, ctx, text);
    return text;
  }

 private:
  struct Section {
    std::string key;
    std::string doc;
    std::string allowed;
    std::function<void(const toml::node* node, const toml::table& root, const ReadContext& ctx,
                       Root& out)>
        read;
    std::function<void(const Root& in, const WriteContext& ctx, std::string& text)> write;
  };

  template <typename S, typename Get, typename GetConst>
  DocumentSchema& table_with(std::string key, TableSchema<S> schema, std::string doc, Get get,
                             GetConst get_const) {
    Section section;
    section.key = key;
    section.doc = std::move(doc);
    section.allowed = "a table of: " + schema.key_list();
    section.read = [key, schema, get, allowed = section.allowed](
                       const toml::node* node, const toml::table& root, const ReadContext& ctx,
                       Root& out) {
      if (node == nullptr) {
        // Absent table: its optional keys keep their defaults, required ones are reported.
        const toml::table empty;
        schema.read(empty, root.source(), ctx, key, get(out));
        return;
      }
      const toml::table* table = node->as_table();
      if (table == nullptr) fail_wrong_type(ctx, *node, key, "table", allowed);
      schema.read(*table, table->source(), ctx, key, get(out));
    };
    section.write = [key, schema, get_const, doc = section.doc](
                        const Root& in, const WriteContext& ctx, std::string& text) {
      text += "\n# " + doc + "\n[" + key + "]\n";
      schema.write(get_const(in), ctx, text);
    };
    sections_.push_back(std::move(section));
    return *this;
  }

  void reject_unknown_tables(const toml::table& root, const ReadContext& ctx) const {
    std::vector<std::string> known;
    std::string known_list;
    for (const Section& section : sections_) {
      known.push_back(section.key);
      known_list += (known_list.empty() ? "" : ", ") + section.key;
    }
    const toml::key* first = nullptr;
    for (auto&& [key, node] : root) {
      const bool is_known = std::find(known.begin(), known.end(), key.str()) != known.end();
      if (!is_known && (first == nullptr || precedes(key.source(), first->source()))) first = &key;
    }
    if (first != nullptr) fail_unknown_key(ctx, *first, "", known, known_list);
  }

  std::vector<std::string> title_;
  std::vector<Section> sections_;
  std::vector<Check> checks_;
};

// The node at a dotted path such as "materials[2].label", or nullptr. For checks that point at a
// value after the whole document was read.
inline const toml::node* node_at(const toml::table& root, std::string_view path) {
  return root.at_path(path).node();
}

}  // namespace ultrasim::config
