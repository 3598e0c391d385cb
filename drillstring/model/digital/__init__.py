"""The digital controller: sensing, control law and top drive, compiled, on one block.

Each part is declared with its compiled code and its section of the block in one module: the
laws (:mod:`drillstring.model.laws`), the top drive (:mod:`drillstring.model.topdrive`), the
sensing (:mod:`drillstring.model.sensing`) and the controller's timing
(:mod:`drillstring.model.timing`). Here is their assembly: ``layout`` the block laid out from the
parts' sections, ``block`` one sample of all of them (the function every host calls), ``loop``
the sampled closed loop on the engine's kernel, ``controller`` the Python side
(:class:`~drillstring.model.digital.controller.DigitalController`). ``docs/controllers.md``
describes what they compute.
"""
