#include "pumeta/nn/sparse/sparse_batch_norm.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/nn/batch_norm.h"

namespace pumeta {

SparseTensor sparse_batch_norm(const SparseTensor& x, const ParamMap& params,
                               const std::string& prefix, const BatchNormContext& context) {
    if (!context.batch_statistics) {
        if (!context.running) throw InternalError("batch norm '" + prefix + "' without buffers");
        return x.with_features(
            batch_norm_running_stats(x.features(), params, *context.running, prefix, context.eps));
    }
    // One site has no variance to estimate: it normalises to beta and is not recorded.
    if (context.update && x.size() >= 2)
        update_running_stats(x.features().detach(), *context.update, prefix, context.momentum);
    return x.with_features(batch_norm_batch_stats(x.features(), params, prefix, context.eps));
}

}  // namespace pumeta
