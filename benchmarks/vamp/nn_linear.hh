// VAMP 0.6.4's `src/impl/vamp/planning/nn.hh` (Apache-2.0, Copyright the VAMP authors) with
// nigh's k-d tree replaced by an exact linear scan: nigh is not on the package registries.
// `build.sh` copies this file over the original before compiling `driver.cc`. Only the
// `NN` type below is new; `NNFloatArray` and `NNNode` are VAMP's.
#pragma once

#include <vamp/vector.hh>
#include <vamp/vector/eigen.hh>

#include <optional>
#include <utility>
#include <vector>
#include <limits>

namespace vamp::planning
{
    template <std::size_t dim_>
    struct NNFloatArray
    {
        inline static constexpr auto dim = dim_;
        float *v;

        // NOTE: This lint (google-explicit-constructor) is incorrect in this case; we want implicit
        // conversion
        inline operator Eigen::Matrix<float, dim_, 1>() const
        {
            return EigenFloatVectorMap<dim_>(v);
        }
    };
}  // namespace vamp::planning

namespace vamp::planning
{
    template <std::size_t dimension>
    struct NNNode
    {
        std::size_t index;
        NNFloatArray<dimension> array;

        [[nodiscard]] inline auto as_vector() const noexcept -> FloatVector<dimension>
        {
            return FloatVector<dimension>(array.v);
        }
    };

    // Exact linear-scan nearest neighbour in place of nigh's k-d tree (nigh is not on the
    // package registries): the same nearest state, ties to the first inserted.
    template <std::size_t dimension, std::size_t batch = 128>
    struct NN
    {
        std::vector<NNNode<dimension>> nodes;

        inline void insert(const NNNode<dimension> &node) { nodes.push_back(node); }
        [[nodiscard]] inline auto size() const noexcept -> std::size_t { return nodes.size(); }
        inline void clear() { nodes.clear(); }

        inline auto nearest(const NNFloatArray<dimension> &key) const
            -> std::optional<std::pair<NNNode<dimension>, float>>
        {
            if (nodes.empty())
            {
                return std::nullopt;
            }
            const auto q = FloatVector<dimension>(key.v);
            std::size_t best = 0;
            float best_d = std::numeric_limits<float>::infinity();
            for (std::size_t i = 0; i < nodes.size(); ++i)
            {
                const float d = (FloatVector<dimension>(nodes[i].array.v) - q).l2_norm();
                if (d < best_d)
                {
                    best_d = d;
                    best = i;
                }
            }
            return std::make_pair(nodes[best], best_d);
        }
    };
}  // namespace vamp::planning
