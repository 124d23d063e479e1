;; A component built for a later interface version than the host runs.
(component
  (instance $node)
  (export "spindlelab:plugin/node@0.9.0" (instance $node))
)
