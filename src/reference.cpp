#include "pwcontact/reference.hpp"

namespace pwcontact {
template ContactResult<double> contact_function<double>(const double*, const double*,
                                                        const double*, const ReferenceOptions&);
template ContactResult<float> contact_function<float>(const float*, const float*, const float*,
                                                      const ReferenceOptions&);
template ContactGeometry<double> contact_geometry<double>(const double*, const double*,
                                                          const double*, double);
template ContactGeometry<float> contact_geometry<float>(const float*, const float*, const float*,
                                                        float);
}  // namespace pwcontact
