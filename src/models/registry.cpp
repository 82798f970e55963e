#include "flexipde/pointwise.hpp"

namespace flexipde {

// Filled by the models' own registrations (FLEXIPDE_REGISTER_MODEL) before main: a function-local
// map, so that it exists whatever order the static registrations run in.
std::map<std::string, ModelFactory> &model_registry() {
  static std::map<std::string, ModelFactory> registry;
  return registry;
}

ModelRegistration::ModelRegistration(const char *name, ModelFactory factory) { model_registry()[name] = std::move(factory); }

std::string model_names() {
  std::string s;
  for (auto &kv : model_registry()) s += (s.empty() ? "" : ", ") + kv.first;
  return s;
}

PetscErrorCode create_model(MPI_Comm comm, const std::string &name, std::unique_ptr<Model> &model) {
  PetscFunctionBeginUser;
  auto it = model_registry().find(name);
  PetscCheck(it != model_registry().end(), comm, PETSC_ERR_ARG_UNKNOWN_TYPE, "Unknown model '%s': choose one of %s",
             name.c_str(), model_names().c_str());
  model = it->second();
  PetscFunctionReturn(0);
}

} // namespace flexipde
