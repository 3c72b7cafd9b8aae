#include "pwcontact/batch.hpp"

namespace pwcontact {

template <class T>
void PairBatch<T>::resize(std::size_t n) {
  for (auto& v : r12_) v.resize(n);
  for (auto& v : q1_) v.resize(n);
  for (auto& v : q2_) v.resize(n);
}

template <class T>
void PairBatch<T>::reserve(std::size_t n) {
  for (auto& v : r12_) v.reserve(n);
  for (auto& v : q1_) v.reserve(n);
  for (auto& v : q2_) v.reserve(n);
}

template <class T>
void PairBatch<T>::push_back(const T r12[3], const T q1[6], const T q2[6]) {
  for (int k = 0; k < 3; ++k) r12_[k].push_back(r12[k]);
  for (int k = 0; k < 6; ++k) {
    q1_[k].push_back(q1[k]);
    q2_[k].push_back(q2[k]);
  }
}

template <class T>
void PairBatch<T>::set(std::size_t i, const T r12[3], const T q1[6], const T q2[6]) {
  for (int k = 0; k < 3; ++k) r12_[k][i] = r12[k];
  for (int k = 0; k < 6; ++k) {
    q1_[k][i] = q1[k];
    q2_[k][i] = q2[k];
  }
}

template <class T>
void PairBatch<T>::get(std::size_t i, T r12[3], T q1[6], T q2[6]) const {
  for (int k = 0; k < 3; ++k) r12[k] = r12_[k][i];
  for (int k = 0; k < 6; ++k) {
    q1[k] = q1_[k][i];
    q2[k] = q2_[k][i];
  }
}

template <class T>
PairBatchView<T> PairBatch<T>::view() const noexcept {
  PairBatchView<T> v;
  v.size = size();
  for (int k = 0; k < 3; ++k) v.r12[k] = r12_[k].data();
  for (int k = 0; k < 6; ++k) {
    v.q1[k] = q1_[k].data();
    v.q2[k] = q2_[k].data();
  }
  return v;
}

template class PairBatch<double>;
template class PairBatch<float>;

}  // namespace pwcontact
