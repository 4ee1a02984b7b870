#include "pumeta/models/torch_archive.h"

#include <ATen/ATen.h>
#include <c10/util/Exception.h>
#include <caffe2/serialize/inline_container.h>
#include <caffe2/serialize/read_adapter_interface.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <variant>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

/// A storage named by a persistent id: `numel` elements of `dtype` in record data/<key>.
struct Storage {
    at::ScalarType dtype = at::kFloat;
    at::Tensor data;  ///< 1-D, numel elements
};

struct Global {
    std::string module, name;
};

// Containers live in the unpickler's arena and values point into it, so that copying a value
// (BINGET) is cheap however large it is, and freeing nested or cyclic containers recurses
// nowhere: a forged file can neither blow up the time nor overflow the stack.
struct Value;
struct Sequence {
    std::vector<Value> items;
};
struct Mapping {
    std::vector<std::pair<Value, Value>> items;
};
struct Tuple {
    const Sequence* seq;
};
struct List {
    Sequence* seq;
};
struct Dict {
    Mapping* map;
};
using Text = std::shared_ptr<const std::string>;

struct None {};
struct Mark {};

struct Value {
    std::variant<None, Mark, bool, int64_t, Text, Tuple, List, Dict, Global,
                 std::shared_ptr<Storage>, at::Tensor>
        v;
};

const char* kind_name(const Value& value) {
    static const char* names[] = {"None", "mark", "bool",   "int",     "str",   "tuple",
                                  "list", "dict", "global", "storage", "tensor"};
    return names[value.v.index()];
}

/// The largest tensor or storage accepted (elements); released upsamplers hold well under a
/// million parameters, so this only stops forged sizes from allocating.
constexpr int64_t kMaxElements = int64_t{1} << 31;

bool allowed_global(const Global& global) {
    return (global.module == "collections" && global.name == "OrderedDict") ||
           (global.module == "torch" &&
            (global.name == "FloatStorage" || global.name == "LongStorage")) ||
           (global.module == "torch._utils" && global.name == "_rebuild_tensor_v2");
}

class Unpickler {
  public:
    Unpickler(const std::string& path, std::string_view bytes,
              const std::function<std::string(const std::string&)>& load_record)
        : path_(path), bytes_(bytes), load_record_(load_record) {}

    /// The pickle's value. Containers in it stay valid while this unpickler lives.
    Value run() {
        while (true) {
            if (pos_ >= bytes_.size()) fail("data.pkl ends before STOP");
            op_offset_ = pos_;
            const auto op = static_cast<uint8_t>(bytes_[pos_++]);
            switch (op) {
                case 0x80:
                    take(1);
                    break;  // PROTO
                case '.':   // STOP
                    if (stack_.size() != 1) fail("STOP with {} values on the stack", stack_.size());
                    return pop();
                case 'c': {  // GLOBAL
                    Global global;
                    global.module = line();
                    global.name = line();
                    if (!allowed_global(global))
                        fail("global {}.{} is not one a state dict uses", global.module,
                             global.name);
                    push({global});
                    break;
                }
                case '(':
                    push({Mark{}});
                    break;
                case '}':
                    push({Dict{&maps_.emplace_back()}});
                    break;
                case ']':
                    push({List{&sequences_.emplace_back()}});
                    break;
                case ')':
                    push({Tuple{&sequences_.emplace_back()}});
                    break;
                case 't':
                    push({tuple_of(pop_to_mark())});
                    break;
                case 0x85:
                    push({tuple_of(pop_n(1))});
                    break;  // TUPLE1
                case 0x86:
                    push({tuple_of(pop_n(2))});
                    break;  // TUPLE2
                case 0x87:
                    push({tuple_of(pop_n(3))});
                    break;  // TUPLE3
                case 'K':
                    push({static_cast<int64_t>(little_endian(1))});
                    break;  // BININT1
                case 'M':
                    push({static_cast<int64_t>(little_endian(2))});
                    break;  // BININT2
                case 'J':   // BININT
                    push({static_cast<int64_t>(static_cast<int32_t>(little_endian(4)))});
                    break;
                case 0x8a:
                    push({long1()});
                    break;   // LONG1
                case 'X': {  // BINUNICODE
                    const uint64_t length = little_endian(4);
                    push({std::make_shared<const std::string>(take(length))});
                    break;
                }
                case 'N':
                    push({None{}});
                    break;
                case 0x88:
                    push({true});
                    break;  // NEWTRUE
                case 0x89:
                    push({false});
                    break;  // NEWFALSE
                case 'q':
                    memo_[little_endian(1)] = top();
                    break;  // BINPUT
                case 'r':
                    memo_[little_endian(4)] = top();
                    break;  // LONG_BINPUT
                case 'h':
                    push(memo(little_endian(1)));
                    break;  // BINGET
                case 'j':
                    push(memo(little_endian(4)));
                    break;  // LONG_BINGET
                case 'Q':
                    push(persistent_load(pop()));
                    break;   // BINPERSID
                case 'R': {  // REDUCE
                    Value args = pop();
                    Value callable = pop();
                    push(reduce(callable, args));
                    break;
                }
                case 'b':  // BUILD: the state (an OrderedDict's _metadata) is not needed
                    pop();
                    top();
                    break;
                case 's': {  // SETITEM
                    Value value = pop();
                    Value key = pop();
                    dict_on_top().emplace_back(std::move(key), std::move(value));
                    break;
                }
                case 'u': {  // SETITEMS
                    std::vector<Value> items = pop_to_mark();
                    if (items.size() % 2 != 0) fail("SETITEMS with an odd number of values");
                    auto& dict = dict_on_top();
                    for (size_t i = 0; i < items.size(); i += 2)
                        dict.emplace_back(std::move(items[i]), std::move(items[i + 1]));
                    break;
                }
                case 'a': {  // APPEND
                    Value value = pop();
                    list_on_top().push_back(std::move(value));
                    break;
                }
                case 'e': {  // APPENDS
                    std::vector<Value> items = pop_to_mark();
                    auto& list = list_on_top();
                    for (Value& item : items) list.push_back(std::move(item));
                    break;
                }
                default:
                    fail("opcode 0x{:02x} is not one a state dict uses", op);
            }
        }
    }

  private:
    template <typename... Args>
    [[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) const {
        throw_input_error(path_, "{} (data.pkl byte {})",
                          fmt::format(format, std::forward<Args>(args)...), op_offset_);
    }

    std::string_view take(uint64_t count) {
        if (count > bytes_.size() - pos_) fail("data.pkl ends inside an opcode");
        std::string_view out = bytes_.substr(pos_, count);
        pos_ += count;
        return out;
    }
    uint64_t little_endian(int count) {
        std::string_view raw = take(count);
        uint64_t value = 0;
        for (int i = count - 1; i >= 0; --i) value = value << 8 | static_cast<uint8_t>(raw[i]);
        return value;
    }
    int64_t long1() {
        const uint64_t count = little_endian(1);
        if (count > 8) fail("LONG1 of {} bytes is beyond 64 bits", count);
        if (count == 0) return 0;
        uint64_t value = little_endian(static_cast<int>(count));
        if (count < 8 && (value >> (8 * count - 1)) & 1) value |= ~uint64_t{0} << (8 * count);
        return static_cast<int64_t>(value);
    }
    std::string line() {
        const size_t end = bytes_.find('\n', pos_);
        if (end == std::string_view::npos) fail("GLOBAL without its newline");
        std::string out(bytes_.substr(pos_, end - pos_));
        pos_ = end + 1;
        return out;
    }

    Tuple tuple_of(std::vector<Value> items) {
        Sequence& seq = sequences_.emplace_back();
        seq.items = std::move(items);
        return {&seq};
    }
    void push(Value value) {
        if (std::holds_alternative<Mark>(value.v)) marks_.push_back(stack_.size());
        stack_.push_back(std::move(value));
    }
    Value& top() {
        if (stack_.empty()) fail("the stack is empty");
        if (std::holds_alternative<Mark>(stack_.back().v)) fail("a mark where a value is expected");
        return stack_.back();
    }
    Value pop() {
        Value value = std::move(top());
        stack_.pop_back();
        return value;
    }
    std::vector<Value> pop_n(size_t count) {
        std::vector<Value> items(count);
        for (size_t i = count; i-- > 0;) items[i] = pop();
        return items;
    }
    std::vector<Value> pop_to_mark() {
        if (marks_.empty()) fail("no mark to pop to");
        const auto mark = static_cast<std::ptrdiff_t>(marks_.back());
        marks_.pop_back();
        std::vector<Value> items(std::make_move_iterator(stack_.begin() + mark + 1),
                                 std::make_move_iterator(stack_.end()));
        stack_.resize(static_cast<size_t>(mark));
        return items;
    }
    Value memo(uint64_t key) {
        auto found = memo_.find(key);
        if (found == memo_.end()) fail("memo entry {} was never stored", key);
        return found->second;
    }
    std::vector<std::pair<Value, Value>>& dict_on_top() {
        Dict* dict = std::get_if<Dict>(&top().v);
        if (!dict) fail("SETITEM on a {}, not a dict", kind_name(top()));
        return dict->map->items;
    }
    std::vector<Value>& list_on_top() {
        List* list = std::get_if<List>(&top().v);
        if (!list) fail("APPEND on a {}, not a list", kind_name(top()));
        return list->seq->items;
    }

    const std::vector<Value>& tuple(const Value& value, size_t size, const char* what) {
        const Tuple* items = std::get_if<Tuple>(&value.v);
        if (!items || items->seq->items.size() != size) fail("{} is not a {}-tuple", what, size);
        return items->seq->items;
    }
    int64_t integer(const Value& value, const char* what) {
        const int64_t* number = std::get_if<int64_t>(&value.v);
        if (!number) fail("{} is a {}, not an int", what, kind_name(value));
        return *number;
    }
    const std::string& string(const Value& value, const char* what) {
        const Text* text = std::get_if<Text>(&value.v);
        if (!text) fail("{} is a {}, not a str", what, kind_name(value));
        return **text;
    }
    std::vector<int64_t> sizes(const Value& value, const char* what) {
        const Tuple* items = std::get_if<Tuple>(&value.v);
        if (!items || items->seq->items.size() > 8)
            fail("{} is not a tuple of at most 8 ints", what);
        std::vector<int64_t> out;
        for (const Value& item : items->seq->items) {
            out.push_back(integer(item, what));
            if (out.back() < 0 || out.back() > kMaxElements) fail("{} holds {}", what, out.back());
        }
        return out;
    }

    Value persistent_load(const Value& id) {
        const std::vector<Value>& items = tuple(id, 5, "a persistent id");
        const std::string& kind = string(items[0], "the persistent id's kind");
        if (kind != "storage") fail("a persistent id of kind '{}', not 'storage'", kind);
        const Global* type = std::get_if<Global>(&items[1].v);
        if (!type || type->module != "torch" || !allowed_global(*type))
            fail("a storage type that is not FloatStorage or LongStorage");
        const std::string& key = string(items[2], "a storage key");
        string(items[3], "a storage location");  // where it was saved: "cpu", "cuda:0"
        const int64_t numel = integer(items[4], "a storage size");
        if (numel < 0 || numel > kMaxElements) fail("a storage of {} elements", numel);
        auto cached = storages_.find(key);
        if (cached != storages_.end()) {
            if (cached->second->data.numel() != numel)
                fail("storage {} named with {} and {} elements", key, cached->second->data.numel(),
                     numel);
            return {cached->second};
        }
        auto storage = std::make_shared<Storage>();
        storage->dtype = type->name == "FloatStorage" ? at::kFloat : at::kLong;
        const std::string bytes = load_record_(key);
        const size_t element = storage->dtype == at::kFloat ? 4 : 8;
        if (bytes.size() != static_cast<size_t>(numel) * element)
            fail("record data/{} holds {} bytes, not the {} of {} elements", key, bytes.size(),
                 static_cast<size_t>(numel) * element, numel);
        storage->data = at::empty({numel}, at::TensorOptions().dtype(storage->dtype));
        if (numel > 0) std::memcpy(storage->data.data_ptr(), bytes.data(), bytes.size());
        storages_.emplace(key, storage);
        return {storage};
    }

    Value reduce(const Value& callable, const Value& args) {
        const Global* global = std::get_if<Global>(&callable.v);
        if (!global) fail("REDUCE on a {}, not a global", kind_name(callable));
        if (global->name == "OrderedDict") {
            tuple(args, 0, "OrderedDict's arguments");
            return {Dict{&maps_.emplace_back()}};
        }
        if (global->name == "_rebuild_tensor_v2")
            return {rebuild_tensor(tuple(args, 6, "_rebuild_tensor_v2's arguments"))};
        fail("REDUCE on {}.{}", global->module, global->name);
    }

    at::Tensor rebuild_tensor(const std::vector<Value>& args) {
        const auto* storage = std::get_if<std::shared_ptr<Storage>>(&args[0].v);
        if (!storage) fail("a tensor whose storage is a {}", kind_name(args[0]));
        const int64_t offset = integer(args[1], "a tensor's storage offset");
        const std::vector<int64_t> size = sizes(args[2], "a tensor's size");
        const std::vector<int64_t> stride = sizes(args[3], "a tensor's stride");
        if (size.size() != stride.size())
            fail("a tensor with {} sizes and {} strides", size.size(), stride.size());
        const int64_t numel = (*storage)->data.numel();
        // The last element the view reaches must lie inside the storage.
        int64_t elements = 1, last = offset;
        for (size_t i = 0; i < size.size() && elements > 0; ++i) {
            if (size[i] == 0) {
                elements = 0;
                break;
            }
            if (size[i] > kMaxElements / elements)
                fail("a tensor of over {} elements", kMaxElements);
            elements *= size[i];
            last += (size[i] - 1) * stride[i];
        }
        if (offset < 0 || offset > kMaxElements || (elements > 0 && last >= numel))
            fail("a tensor reaching element {} of a storage of {}", last, numel);
        if (elements == 0) return at::empty(size, at::TensorOptions().dtype((*storage)->dtype));
        return (*storage)
            ->data.as_strided(size, stride, offset)
            .clone(at::MemoryFormat::Contiguous);
    }

    const std::string& path_;
    std::string_view bytes_;
    const std::function<std::string(const std::string&)>& load_record_;
    size_t pos_ = 0, op_offset_ = 0;
    std::vector<Value> stack_;
    std::vector<size_t> marks_;
    std::map<uint64_t, Value> memo_;
    std::map<std::string, std::shared_ptr<Storage>> storages_;
    std::deque<Sequence> sequences_;
    std::deque<Mapping> maps_;
};

}  // namespace

StateDict unpickle_state_dict(const std::string& path, std::string_view pickle,
                              const std::function<std::string(const std::string&)>& load_record) {
    Unpickler machine(path, pickle, load_record);
    const Value root = machine.run();
    const Dict* dict = std::get_if<Dict>(&root.v);
    if (!dict) throw_input_error(path, "data.pkl holds a {}, not a state dict", kind_name(root));
    StateDict out;
    for (const auto& [key, value] : dict->map->items) {
        const Text* name = std::get_if<Text>(&key.v);
        if (!name) throw_input_error(path, "a state dict key that is a {}", kind_name(key));
        const at::Tensor* tensor = std::get_if<at::Tensor>(&value.v);
        if (!tensor)
            throw_input_error(path, "state dict entry '{}' is a {}, not a tensor", **name,
                              kind_name(value));
        out.emplace_back(**name, *tensor);
    }
    return out;
}

}  // namespace pumeta

namespace pumeta {

namespace {

/// An archive in memory. Unlike LibTorch's MemoryReadAdapter it never reads past the end
/// (a forged zip directory can name any offset): a read there returns fewer bytes, which the
/// zip reader reports as an error.
class BoundedReadAdapter final : public caffe2::serialize::ReadAdapterInterface {
  public:
    explicit BoundedReadAdapter(std::string_view bytes) : bytes_(bytes) {}
    size_t size() const override { return bytes_.size(); }
    size_t read(uint64_t pos, void* buf, size_t n, const char* what = "") const override {
        if (pos >= bytes_.size()) return 0;
        const size_t count = std::min<uint64_t>(n, bytes_.size() - pos);
        std::memcpy(buf, bytes_.data() + pos, count);
        return count;
    }

  private:
    std::string_view bytes_;
};

/// The first line of a LibTorch error (its messages carry a stack trace after it).
std::string first_line(const char* what) {
    std::string text(what);
    return text.substr(0, text.find('\n'));
}

}  // namespace

StateDict parse_torch_state_dict(const std::string& path, std::string_view bytes) {
    using caffe2::serialize::PyTorchStreamReader;
    std::unique_ptr<PyTorchStreamReader> reader;
    try {
        reader = std::make_unique<PyTorchStreamReader>(std::make_shared<BoundedReadAdapter>(bytes));
    } catch (const c10::Error& error) {
        throw_input_error(path, "not a torch.save archive ({})", first_line(error.what()));
    }
    auto record = [&](const std::string& name) {
        try {
            if (!reader->hasRecord(name))
                throw_input_error(path, "the archive has no record {}", name);
            auto [data, size] = reader->getRecord(name);
            return std::string(static_cast<const char*>(data.get()), size);
        } catch (const c10::Error& error) {
            throw_input_error(path, "record {} cannot be read ({})", name,
                              first_line(error.what()));
        }
    };
    if (reader->hasRecord("byteorder") && record("byteorder") != "little")
        throw_input_error(path, "storages saved big-endian; only little-endian files are read");
    const std::string pickle = record("data.pkl");
    return unpickle_state_dict(path, pickle,
                               [&](const std::string& key) { return record("data/" + key); });
}

StateDict read_torch_state_dict(const std::string& path) {
    std::ifstream file(path, std::ios::binary);
    if (!file) throw_input_error(path, "cannot be opened");
    const std::string bytes((std::istreambuf_iterator<char>(file)),
                            std::istreambuf_iterator<char>());
    if (file.bad()) throw_input_error(path, "cannot be read");
    return parse_torch_state_dict(path, bytes);
}

}  // namespace pumeta
