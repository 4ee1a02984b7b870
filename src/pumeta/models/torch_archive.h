// Reading released PyTorch weights: a `torch.save` archive (a zip of a pickle and raw storage
// records) of a state dict, without Python and without LibTorch's own unpickler, which cannot
// map CUDA storages to the CPU and rejects a state dict's `_metadata` (docs/design.md,
// "Importing released weights").
//
// The pickle is read by a small machine for the subset torch.save writes for a state dict
// (protocol 2): the opcodes PROTO, GLOBAL, MARK, EMPTY_DICT, EMPTY_TUPLE, EMPTY_LIST, TUPLE,
// TUPLE1-3, BININT, BININT1, BININT2, LONG1, BINUNICODE, NONE, NEWTRUE, NEWFALSE, BINPUT,
// LONG_BINPUT, BINGET, LONG_BINGET, BINPERSID, REDUCE, BUILD, SETITEM, SETITEMS, APPEND,
// APPENDS, STOP, and the globals collections.OrderedDict, torch.FloatStorage,
// torch.LongStorage and torch._utils._rebuild_tensor_v2. Anything else is refused.
#pragma once

#include <ATen/core/Tensor.h>

#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pumeta {

/// A state dict in the order it was saved: module path ("feature_extractor.conv_init.0.weight")
/// -> a contiguous CPU tensor (float32 or int64) that owns its memory.
using StateDict = std::vector<std::pair<std::string, at::Tensor>>;

/// Reads the state dict saved by `torch.save(model.state_dict(), path)`, whatever device its
/// storages were saved from. InputError "<path>: ..." (one line: the record, opcode, global or
/// byte offset at fault) for a missing, foreign, truncated or corrupted file, and for a pickle
/// that holds anything but a dict of tensors.
StateDict read_torch_state_dict(const std::string& path);

/// The same from the archive's bytes in memory; `path` names it in messages.
StateDict parse_torch_state_dict(const std::string& path, std::string_view bytes);

/// The pickle machine alone: the state dict in `pickle` (an archive's data.pkl), whose
/// storages are the records `load_record(key)` returns (the bytes of `data/<key>`).
/// InputError "<path>: ..." as read_torch_state_dict.
StateDict unpickle_state_dict(const std::string& path, std::string_view pickle,
                              const std::function<std::string(const std::string&)>& load_record);

}  // namespace pumeta
