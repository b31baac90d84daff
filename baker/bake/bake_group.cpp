#include "baker/bake/bake_group.h"

#include <algorithm>
#include <cstdlib>
#include <numeric>

namespace nrad {

bool launchedByMpi() {
    for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
        if (std::getenv(v)) return true;
    return false;
}

std::vector<int> assignByCost(const std::vector<double>& costs, int size) {
    std::vector<size_t> order(costs.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return costs[a] > costs[b]; });
    std::vector<double> load(size_t(std::max(1, size)), 0.0);
    std::vector<int> owner(costs.size(), 0);
    for (size_t i : order) {
        const size_t r = size_t(std::min_element(load.begin(), load.end()) - load.begin());  // the first of the least
        owner[i] = int(r);
        load[r] += costs[i];
    }
    return owner;
}

}  // namespace nrad
