"""The ground every layer stands on: configuration constants (:mod:`.config`), the engine's
errors (:mod:`.errors`) and declared parameter records (:mod:`.records`: fields with unit,
bounds and description, validated once, and their JSON form)."""
